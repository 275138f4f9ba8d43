//! The user guide cannot rot, on the side of `verify`:
//!
//! - every key the case-file parser accepts is in `docs/reference/case-file.md`, and every key
//!   listed there is accepted (the keys are harvested from the parser's own error messages, see
//!   `tests/guide/mod.rs`, not written down here);
//! - every flag and subcommand of `verify` is in `docs/reference/cli.md`, and every flag listed
//!   there for `verify` exists (read from clap's description of the command line);
//! - every `verify` command line in the code blocks of `README.md` and `docs/` parses;
//! - the cheap `verify` command lines of the guide run as written ([`CHEAP_COMMANDS`]);
//! - `verify --help` exits successfully.

use crate::guide;

use clap::{CommandFactory, Parser};
use contact_input::sides::parse_sides;
use contact_input::FileKind;
use guide::{
    assert_no_problems, compare_cli, compare_keys, doc_commands, expand, harvest,
    names_in_use_list, read, reference_keys, run_cheap_commands, workspace_root, CommandSpec,
    Entries, Keys,
};
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::OnceLock;
use verify::case::{parse_case_file, Case};
use verify::cli::{Cli, BUILT_IN_CASES};

const CASE_REFERENCE: &str = "docs/reference/case-file.md";
const CLI_REFERENCE: &str = "docs/reference/cli.md";
/// Where the rules for the tables with free keys are ([`map_rules`]).
const THIS_FILE: &str = "tests/docs.rs";

fn root() -> PathBuf {
    workspace_root(env!("CARGO_MANIFEST_DIR"))
}

/// The box sides, as the validation of `domain.sides` names them in its error for an unknown
/// side; each is checked to be accepted.
fn side_names() -> Vec<String> {
    let unknown = BTreeMap::from([(guide::PROBE.to_string(), "clamped".to_string())]);
    let message = parse_sides::<3>(FileKind::Case, "probe.toml", "domain.sides", &unknown)
        .expect_err("an unknown side is refused")
        .to_string();
    let names = names_in_use_list(&message);
    for name in &names {
        let side = BTreeMap::from([(name.clone(), "clamped".to_string())]);
        if let Err(e) = parse_sides::<3>(FileKind::Case, "probe.toml", "domain.sides", &side) {
            panic!("the side `{name}` of the message `{message}` is refused: {e}");
        }
    }
    names
}

/// The study sets (`studies.order1`, …), as the validation of a case names them in its error
/// for an unknown set.
fn study_set_names() -> Vec<String> {
    let (name, text) = BUILT_IN_CASES
        .iter()
        .find(|(_, text)| parse_case_file(text, "probe.toml").is_ok_and(|file| file.dim == 2))
        .expect("a built-in 2D case");
    let mut document: toml::Table = toml::from_str(text).expect("a built-in case is TOML");
    document
        .entry("studies")
        .or_insert_with(|| toml::Value::Table(toml::Table::new()))
        .as_table_mut()
        .expect("`studies` is a table")
        .insert(
            guide::PROBE.to_string(),
            toml::Value::Table(toml::Table::new()),
        );
    let origin = format!("built-in:{name}");
    let text = toml::to_string(&document).expect("TOML");
    let file = parse_case_file(&text, &origin).expect("an empty study set parses");
    let message = match Case::<2>::new(file, &origin) {
        Ok(_) => panic!("the study set `{}` is accepted", guide::PROBE),
        Err(e) => e.to_string(),
    };
    assert!(
        message.contains(&format!("studies.{}", guide::PROBE)),
        "the error names another key: {message}"
    );
    names_in_use_list(&message)
}

/// How the reference writes the entries of each table with free keys (a map) of a case file.
fn map_rules() -> Vec<(&'static str, Entries)> {
    vec![
        ("constants", Entries::Placeholder("<name>")),
        ("domain.sides", Entries::Names(side_names())),
        ("studies", Entries::Names(study_set_names())),
    ]
}

/// Every key of a case file as the reference writes it, harvested from the parser, starting
/// from each built-in case.
fn case_keys() -> &'static Keys {
    static KEYS: OnceLock<Keys> = OnceLock::new();
    KEYS.get_or_init(|| {
        let bases: Vec<(String, String)> = BUILT_IN_CASES
            .iter()
            .map(|(name, text)| (format!("built-in case `{name}`"), text.to_string()))
            .collect();
        let parse = |text: &str| {
            parse_case_file(text, "probe.toml")
                .map(|_| ())
                .map_err(|e| e.to_string())
        };
        let keys = harvest(&bases, &parse);
        let (keys, problems) = expand(&keys, &map_rules(), THIS_FILE);
        assert_no_problems("the tables with free keys of case files", &problems);
        keys
    })
}

fn case_comparison() -> (Vec<String>, Vec<String>, usize) {
    let text = read(&root(), CASE_REFERENCE);
    let (rows, mut problems) = reference_keys(&text, CASE_REFERENCE);
    let (missing, refused) = compare_keys(case_keys(), &rows, CASE_REFERENCE);
    problems.extend(refused);
    (missing, problems, rows.len())
}

#[test]
fn every_case_file_key_is_in_the_reference() {
    let (missing, _, _) = case_comparison();
    eprintln!(
        "{} keys of case files checked against {CASE_REFERENCE}",
        case_keys().len()
    );
    assert_no_problems(
        "keys the case-file parser accepts, missing from the reference (add them there)",
        &missing,
    );
}

#[test]
fn every_key_in_the_case_file_reference_is_accepted_by_the_parser() {
    let (_, refused, rows) = case_comparison();
    eprintln!("{rows} rows of {CASE_REFERENCE} checked against the parser");
    assert!(rows > 0, "no key table found in {CASE_REFERENCE}");
    assert_no_problems(
        "keys of the reference that the case-file parser refuses (fix the reference)",
        &refused,
    );
}

/// `verify` and its subcommands as clap describes them (the `help` subcommand that clap adds is
/// left out: `cli.md` names it in the usage line only).
fn verify_commands() -> Vec<CommandSpec> {
    fn walk(command: &clap::Command, path: Vec<String>, specs: &mut Vec<CommandSpec>) {
        let args = command
            .get_arguments()
            .filter(|arg| !arg.is_hide_set())
            .map(|arg| {
                let value_name = || {
                    arg.get_value_names()
                        .and_then(|names| names.first())
                        .map_or_else(|| arg.get_id().as_str().to_uppercase(), |n| n.to_string())
                };
                guide::ArgSpec {
                    long: arg.get_long().map(str::to_string),
                    short: arg.get_short(),
                    value: (!arg.is_positional() && arg.get_action().takes_values())
                        .then(value_name),
                    positional: arg.is_positional().then(value_name),
                }
            })
            .collect();
        specs.push(CommandSpec {
            path: path.clone(),
            args,
        });
        for sub in command.get_subcommands() {
            if sub.get_name() == "help" || sub.is_hide_set() {
                continue;
            }
            let mut path = path.clone();
            path.push(sub.get_name().to_string());
            walk(sub, path, specs);
        }
    }
    let mut command = Cli::command();
    // adds `--help`, `--version` and the `help` subcommand, as the binary has them
    command.build();
    let mut specs = Vec::new();
    walk(&command, vec!["verify".to_string()], &mut specs);
    specs
}

fn cli_comparison() -> (Vec<String>, Vec<String>, usize, usize) {
    let specs = verify_commands();
    let sections = guide::cli_sections(&read(&root(), CLI_REFERENCE), "verify");
    let (missing, unknown) = compare_cli(&specs, &sections, CLI_REFERENCE);
    let flags = specs.iter().map(|s| s.args.len()).sum();
    let listed = sections
        .iter()
        .flat_map(|s| &s.rows)
        .map(|r| r.longs.len() + r.positionals.len())
        .sum();
    (missing, unknown, flags, listed)
}

#[test]
fn every_verify_flag_and_subcommand_is_in_the_cli_reference() {
    let (missing, _, flags, _) = cli_comparison();
    eprintln!(
        "{flags} arguments of {} commands of `verify` checked against {CLI_REFERENCE}",
        verify_commands().len()
    );
    assert!(
        verify_commands().len() >= 5,
        "`verify` lost its subcommands?"
    );
    assert_no_problems(
        "flags and subcommands of `verify` missing from the reference (add them there)",
        &missing,
    );
}

#[test]
fn every_flag_in_the_cli_reference_exists_in_verify() {
    let (_, unknown, _, listed) = cli_comparison();
    eprintln!("{listed} flags listed for `verify` in {CLI_REFERENCE} checked against clap");
    assert_no_problems(
        "flags listed for `verify` in the reference that `verify` does not have (fix the reference)",
        &unknown,
    );
}

/// Every `verify` command line of the guide's code blocks parses with `verify`'s own parser
/// (they are not run). Lines with a placeholder (a word in capitals such as NAME, FILE or L, a
/// shell variable, `<…>`, `[…]`; see `guide::placeholder`) are skipped; which lines count as
/// `verify` command lines is said by `guide::doc_commands`.
#[test]
fn every_verify_command_in_the_guide_parses() {
    let (commands, skipped) = doc_commands(&root(), "verify");
    let mut problems = Vec::new();
    for command in &commands {
        let argv = std::iter::once("verify").chain(command.args.iter().map(String::as_str));
        if let Err(error) = Cli::try_parse_from(argv) {
            use clap::error::ErrorKind::{DisplayHelp, DisplayVersion};
            if !matches!(error.kind(), DisplayHelp | DisplayVersion) {
                problems.push(format!(
                    "{}:{}: `{}` does not parse: {}",
                    command.file,
                    command.line,
                    command.text,
                    error.render().to_string().trim()
                ));
            }
        }
    }
    eprintln!(
        "{} `verify` command lines of the guide parsed; {} skipped for a placeholder:",
        commands.len(),
        skipped.len()
    );
    for (command, word) in &skipped {
        eprintln!("  {}:{}: `{word}`", command.file, command.line);
    }
    assert!(
        commands.len() >= 5,
        "only {} `verify` command lines found in the guide: the search is broken?",
        commands.len()
    );
    assert_no_problems(
        "`verify` command lines of the guide that do not parse (fix the page)",
        &problems,
    );
}

#[test]
fn verify_help_exits_successfully() {
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_verify"))
        .arg("--help")
        .output()
        .expect("`verify --help` starts");
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        output.status.success() && stdout.contains("Usage: verify"),
        "`verify --help` exited with {}: {stdout}{}",
        output.status,
        String::from_utf8_lossy(&output.stderr)
    );
}

/// The `verify` command lines of the guide that take seconds, run by
/// [`the_cheap_verify_commands_of_the_guide_run`] exactly as written (arguments after
/// `cargo run -p verify --`), with their output folder moved to a scratch folder, and the exit
/// status the page promises: 0 for PASS, 3 for the DRIFTING verdict of the three coarsest 3D
/// levels.
const CHEAP_COMMANDS: &[(&str, &[i32])] = &[
    (
        "--case verification/slip2d.toml --studies h --levels 4 --out /tmp/slip",
        &[0],
    ),
    ("--dim 3 --levels 3", &[3]),
];

/// The cheap command lines of the guide run to the end with the verdict the page states.
#[test]
fn the_cheap_verify_commands_of_the_guide_run() {
    let problems = run_cheap_commands(
        &root(),
        "verify",
        env!("CARGO_BIN_EXE_verify"),
        CHEAP_COMMANDS,
    );
    assert_no_problems(
        "cheap `verify` command lines of the guide that fail",
        &problems,
    );
}
