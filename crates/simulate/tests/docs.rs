//! The user guide cannot rot, on the side of `simulate`:
//!
//! - every key the problem-file parser accepts is in `docs/reference/problem-file.md`, and
//!   every key listed there is accepted (the keys are harvested from the parser's own error
//!   messages, see `tests/guide/mod.rs` at the workspace root, not written down here);
//! - every flag of `simulate` is in `docs/reference/cli.md`, and every flag listed there for
//!   `simulate` exists;
//! - every `simulate` command line in the code blocks of `README.md` and `docs/` parses;
//! - `simulate --help` exits successfully.
//!
//! The command line of `simulate` is a private type of its binary (`src/main.rs`), which a test
//! cannot name; the flags are therefore read from the binary's `--help`, which clap writes
//! from the same description, and a command line of the guide is given to the binary itself in
//! an empty folder, where its problem file does not exist: clap refuses a bad command line with
//! exit status 2 before anything else happens, a good one gets as far as reading the problem
//! file and fails there (status 1), so nothing is computed.

use crate::guide;

use contact_input::sides::parse_sides;
use contact_input::FileKind;
use guide::{
    assert_no_problems, compare_cli, compare_keys, doc_commands, expand, harvest,
    names_in_use_list, read, reference_keys, run_cheap_commands, workspace_root, ArgSpec,
    CommandSpec, DocCommand, Entries, Keys,
};
use simulate::problem::parse_problem_file;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

const PROBLEM_REFERENCE: &str = "docs/reference/problem-file.md";
const CLI_REFERENCE: &str = "docs/reference/cli.md";
/// Where the rules for the tables with free keys are ([`map_rules`]).
const THIS_FILE: &str = "crates/simulate/tests/docs.rs";
const SIMULATE: &str = env!("CARGO_BIN_EXE_simulate");

fn root() -> PathBuf {
    workspace_root(env!("CARGO_MANIFEST_DIR"))
}

/// The box sides, as the validation of `mesh.box.sides` names them in its error for an unknown
/// side; each is checked to be accepted.
fn side_names() -> Vec<String> {
    let prefix = "mesh.box.sides";
    let unknown = BTreeMap::from([(guide::PROBE.to_string(), "clamped".to_string())]);
    let message = parse_sides::<3>(FileKind::Problem, "probe.toml", prefix, &unknown)
        .expect_err("an unknown side is refused")
        .to_string();
    let names = names_in_use_list(&message);
    for name in &names {
        let side = BTreeMap::from([(name.clone(), "clamped".to_string())]);
        if let Err(e) = parse_sides::<3>(FileKind::Problem, "probe.toml", prefix, &side) {
            panic!("the side `{name}` of the message `{message}` is refused: {e}");
        }
    }
    names
}

/// How the reference writes the entries of each table with free keys (a map) of a problem
/// file.
fn map_rules() -> Vec<(&'static str, Entries)> {
    vec![
        ("constants", Entries::Placeholder("<name>")),
        ("mesh.box.sides", Entries::Names(side_names())),
    ]
}

/// The example problems, `crates/simulate/examples/*.toml`.
fn examples() -> Vec<(String, String)> {
    let folder = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples");
    let mut paths: Vec<PathBuf> = std::fs::read_dir(&folder)
        .expect("the examples folder")
        .map(|entry| entry.expect("a folder entry").path())
        .filter(|path| path.extension().is_some_and(|e| e == "toml"))
        .collect();
    paths.sort();
    assert!(
        !paths.is_empty(),
        "no example problem in {}",
        folder.display()
    );
    paths
        .into_iter()
        .map(|path| {
            let text = std::fs::read_to_string(&path).expect("an example problem");
            (path.display().to_string(), text)
        })
        .collect()
}

/// Every key of a problem file as the reference writes it, harvested from the parser,
/// starting from each example problem.
fn problem_keys() -> &'static Keys {
    static KEYS: OnceLock<Keys> = OnceLock::new();
    KEYS.get_or_init(|| {
        let parse = |text: &str| {
            parse_problem_file(text, "probe.toml")
                .map(|_| ())
                .map_err(|e| e.to_string())
        };
        let keys = harvest(&examples(), &parse);
        let (keys, problems) = expand(&keys, &map_rules(), THIS_FILE);
        assert_no_problems("the tables with free keys of problem files", &problems);
        keys
    })
}

fn problem_comparison() -> (Vec<String>, Vec<String>, usize) {
    let text = read(&root(), PROBLEM_REFERENCE);
    let (rows, mut problems) = reference_keys(&text, PROBLEM_REFERENCE);
    let (missing, refused) = compare_keys(problem_keys(), &rows, PROBLEM_REFERENCE);
    problems.extend(refused);
    (missing, problems, rows.len())
}

#[test]
fn every_problem_file_key_is_in_the_reference() {
    let (missing, _, _) = problem_comparison();
    eprintln!(
        "{} keys of problem files checked against {PROBLEM_REFERENCE}",
        problem_keys().len()
    );
    assert_no_problems(
        "keys the problem-file parser accepts, missing from the reference (add them there)",
        &missing,
    );
}

#[test]
fn every_key_in_the_problem_file_reference_is_accepted_by_the_parser() {
    let (_, refused, rows) = problem_comparison();
    eprintln!("{rows} rows of {PROBLEM_REFERENCE} checked against the parser");
    assert!(rows > 0, "no key table found in {PROBLEM_REFERENCE}");
    assert_no_problems(
        "keys of the reference that the problem-file parser refuses (fix the reference)",
        &refused,
    );
}

/// The help of `simulate` with these arguments (`--help` added).
fn help(args: &[String]) -> String {
    let output = Command::new(SIMULATE)
        .args(args)
        .arg("--help")
        .output()
        .expect("`simulate --help` starts");
    assert!(
        output.status.success(),
        "`simulate {} --help` exited with {}: {}",
        args.join(" "),
        output.status,
        String::from_utf8_lossy(&output.stderr)
    );
    String::from_utf8(output.stdout).expect("the help is UTF-8")
}

/// `simulate` (and its subcommands, if it gets any) as its `--help` shows it: the lines of the
/// sections `Arguments:`, `Options:` and `Commands:`, indented by 2 to 6 spaces (clap's
/// layout; a description on a line of its own is indented further).
fn simulate_commands() -> Vec<CommandSpec> {
    fn walk(path: Vec<String>, specs: &mut Vec<CommandSpec>) {
        let text = help(&path[1..]);
        let mut args = Vec::new();
        let mut subcommands = Vec::new();
        let mut section = "";
        for line in text.lines() {
            if !line.starts_with(' ') && line.ends_with(':') {
                section = line.trim_end_matches(':');
                continue;
            }
            let indent = line.len() - line.trim_start().len();
            if !(2..=6).contains(&indent) {
                continue;
            }
            // the argument, up to the two spaces before its description
            let item = line.trim_start().split("  ").next().unwrap_or_default();
            let strip = |v: &str| {
                v.trim_end_matches("...")
                    .trim_start_matches(['[', '<'])
                    .trim_end_matches([']', '>'])
                    .to_string()
            };
            match section {
                "Arguments" => args.push(ArgSpec {
                    long: None,
                    short: None,
                    value: None,
                    positional: Some(strip(item)),
                }),
                "Options" => {
                    let mut arg = ArgSpec {
                        long: None,
                        short: None,
                        value: None,
                        positional: None,
                    };
                    for part in item.split(", ") {
                        let mut words = part.split_whitespace();
                        let flag = words.next().unwrap_or_default();
                        if let Some(long) = flag.strip_prefix("--") {
                            arg.long = Some(long.to_string());
                            arg.value = words.next().map(strip);
                        } else if let Some(short) = flag.strip_prefix('-') {
                            arg.short = short.chars().next();
                        }
                    }
                    args.push(arg);
                }
                "Commands" => {
                    let name = item.split_whitespace().next().unwrap_or_default();
                    if name != "help" {
                        subcommands.push(name.to_string());
                    }
                }
                _ => {}
            }
        }
        assert!(
            !args.is_empty(),
            "no argument read from the help of `{}`:\n{text}",
            path.join(" ")
        );
        specs.push(CommandSpec {
            path: path.clone(),
            args,
        });
        for sub in subcommands {
            let mut path = path.clone();
            path.push(sub);
            walk(path, specs);
        }
    }
    let mut specs = Vec::new();
    walk(vec!["simulate".to_string()], &mut specs);
    specs
}

fn cli_comparison() -> (Vec<String>, Vec<String>, usize, usize) {
    let specs = simulate_commands();
    let sections = guide::cli_sections(&read(&root(), CLI_REFERENCE), "simulate");
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
fn every_simulate_flag_is_in_the_cli_reference() {
    let (missing, _, flags, _) = cli_comparison();
    eprintln!("{flags} arguments of `simulate` checked against {CLI_REFERENCE}");
    assert_no_problems(
        "flags of `simulate` missing from the reference (add them there)",
        &missing,
    );
}

#[test]
fn every_flag_in_the_cli_reference_exists_in_simulate() {
    let (_, unknown, _, listed) = cli_comparison();
    eprintln!("{listed} flags listed for `simulate` in {CLI_REFERENCE} checked against its help");
    assert_no_problems(
        "flags listed for `simulate` in the reference that `simulate` does not have (fix the reference)",
        &unknown,
    );
}

/// Runs `simulate` with the arguments of `command` in the empty folder `folder` and returns
/// clap's error, if it refuses them (exit status 2).
fn refusal(command: &DocCommand, folder: &Path) -> Option<String> {
    // a path that exists outside the empty folder would be run for real
    if let Some(path) = command
        .args
        .iter()
        .find(|arg| Path::new(arg).is_absolute() && Path::new(arg).is_file())
    {
        return Some(format!(
            "names the existing file `{path}`: the test cannot parse it without running it (write the path relative to the workspace)"
        ));
    }
    let mut child = Command::new(SIMULATE)
        .args(&command.args)
        .current_dir(folder)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("`simulate` starts");
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().expect("waiting for `simulate`") {
            break status;
        }
        if start.elapsed() > Duration::from_secs(60) {
            let _ = child.kill();
            let _ = child.wait();
            return Some("ran for a minute instead of stopping at the missing problem file".into());
        }
        std::thread::sleep(Duration::from_millis(10));
    };
    let mut stderr = String::new();
    if let Some(mut pipe) = child.stderr.take() {
        use std::io::Read;
        let _ = pipe.read_to_string(&mut stderr);
    }
    (status.code() == Some(2)).then(|| stderr.trim().to_string())
}

/// Every `simulate` command line of the guide's code blocks parses with `simulate`'s own parser
/// (run in an empty folder, see the top of this file). Lines with a placeholder (a word in
/// capitals such as NAME, FILE or K, a shell variable, `<…>`, `[…]`; see
/// `guide::placeholder`) are skipped; which lines count as `simulate` command lines is said by
/// `guide::doc_commands`.
#[test]
fn every_simulate_command_in_the_guide_parses() {
    let (commands, skipped) = doc_commands(&root(), "simulate");
    let folder = tempfile::tempdir().expect("a temporary folder");
    let mut problems = Vec::new();
    for command in &commands {
        if let Some(error) = refusal(command, folder.path()) {
            problems.push(format!(
                "{}:{}: `{}` does not parse: {error}",
                command.file, command.line, command.text
            ));
        }
    }
    eprintln!(
        "{} `simulate` command lines of the guide parsed; {} skipped for a placeholder:",
        commands.len(),
        skipped.len()
    );
    for (command, word) in &skipped {
        eprintln!("  {}:{}: `{word}`", command.file, command.line);
    }
    assert!(
        commands.len() >= 5,
        "only {} `simulate` command lines found in the guide: the search is broken?",
        commands.len()
    );
    assert_no_problems(
        "`simulate` command lines of the guide that do not parse (fix the page)",
        &problems,
    );
}

#[test]
fn simulate_help_exits_successfully() {
    let output = Command::new(SIMULATE)
        .arg("--help")
        .output()
        .expect("`simulate --help` starts");
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        output.status.success() && stdout.contains("Usage: simulate"),
        "`simulate --help` exited with {}: {stdout}{}",
        output.status,
        String::from_utf8_lossy(&output.stderr)
    );
}

/// The `simulate` command lines of the guide that take seconds, run by
/// [`the_cheap_simulate_commands_of_the_guide_run`] in this order, exactly as written (arguments
/// after `cargo run -p simulate --`), with their output folder moved to a scratch folder (the
/// three on `block_3d.toml` share theirs, so the restart continues the run before it).
const CHEAP_COMMANDS: &[(&str, &[i32])] = &[
    ("crates/simulate/examples/rectangle_2d.toml", &[0]),
    ("crates/simulate/examples/plate_with_hole_2d.toml", &[0]),
    ("crates/simulate/examples/block_3d.toml", &[0]),
    ("crates/simulate/examples/bracket_3d.toml", &[0]),
    (
        "crates/simulate/examples/block_3d.toml --until-step 30 --overwrite",
        &[0],
    ),
    ("crates/simulate/examples/block_3d.toml --resume", &[0]),
];

#[test]
fn the_cheap_simulate_commands_of_the_guide_run() {
    let problems = run_cheap_commands(&root(), "simulate", SIMULATE, CHEAP_COMMANDS);
    assert_no_problems(
        "cheap `simulate` command lines of the guide that fail",
        &problems,
    );
}
