//! What the tests that hold the user guide to the code share (`tests/docs.rs` of `verify`,
//! `crates/simulate/tests/docs.rs` of `simulate`):
//!
//! - [`harvest`]: the keys a TOML parser accepts, read from its own error messages. Its serde
//!   structs refuse unknown keys, so a table holding an unknown key makes the parser fail with
//!   "unknown field `zz_unknown`, expected one of `a`, `b`, …"; a tagged table without its tag
//!   fails with "missing field `kind`", and with an unknown tag with "unknown variant …,
//!   expected one of …". Probing every table in turn (optional tables and every variant of a
//!   tagged table included, created where the starting file lacks them) gives every key.
//! - [`reference_keys`], [`compare_keys`]: the key tables of a reference page against them.
//! - [`cli_sections`], [`compare_cli`]: the flag tables of `docs/reference/cli.md` against a
//!   command line.
//! - [`doc_commands`]: the command lines of the guide's code blocks that invoke a program.
//!
//! Every problem is reported with the file to fix and the key or flag.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use toml::Value;

/// The workspace root, from the manifest folder of the package under test.
pub fn workspace_root(manifest_dir: &str) -> PathBuf {
    Path::new(manifest_dir)
        .join("../..")
        .canonicalize()
        .expect("the workspace root")
}

/// The text of the file `relative` to the workspace `root`.
pub fn read(root: &Path, relative: &str) -> String {
    std::fs::read_to_string(root.join(relative))
        .unwrap_or_else(|e| panic!("cannot read {relative}: {e}"))
}

/// Panics with every problem, one a line, if there is any.
pub fn assert_no_problems(what: &str, problems: &[String]) {
    assert!(
        problems.is_empty(),
        "{what}: {} problem(s):\n{}",
        problems.len(),
        problems.join("\n")
    );
}

// ---------------------------------------------------------------------------------------------
// The keys a parser accepts
// ---------------------------------------------------------------------------------------------

/// The key inserted into a table to make the parser list the keys it accepts.
pub const PROBE: &str = "zz_unknown";

/// The segment of a harvested key that stands for any key of a table with free keys (a map,
/// such as `constants`).
pub const FREE: &str = "*";

/// What the parser accepts at one key.
#[derive(Debug, Clone, Default)]
pub struct Accepted {
    /// For a key of a variant of a tagged table (`laws.viscosity.shear`): the table's key, all
    /// its kinds, and the kinds whose table has this key.
    pub kinds: Option<(String, BTreeSet<String>, BTreeSet<String>)>,
    /// For a tag (`laws.viscosity.kind`) or a key whose value is one of fixed names
    /// (`scheme.contact`): the names.
    pub values: BTreeSet<String>,
}

impl Accepted {
    fn merge(&mut self, other: &Accepted) {
        self.values.extend(other.values.iter().cloned());
        if let Some((table, all, with)) = &other.kinds {
            let (_, mine_all, mine_with) = self
                .kinds
                .get_or_insert_with(|| (table.clone(), BTreeSet::new(), BTreeSet::new()));
            mine_all.extend(all.iter().cloned());
            mine_with.extend(with.iter().cloned());
        }
    }
}

/// Dotted keys as the reference pages write them (`laws.viscosity.kind`), with [`FREE`]
/// segments for the keys of a map (`constants.*`).
pub type Keys = BTreeMap<String, Accepted>;

/// One step from the root of a TOML document to the table being probed.
#[derive(Debug, Clone)]
enum Step {
    /// Into the entry of a table (created if absent).
    Key(String),
    /// Into the first element of an array (an array of one element).
    First,
    /// Into a tagged table of the given kind (created if the table is of another kind).
    Variant { tag: String, kind: String },
}

/// Puts `probe` at the end of `steps` in `node`, keeping whatever else the document holds
/// along the way.
fn set(node: &mut Value, steps: &[Step], probe: Value) {
    match steps.split_first() {
        None => *node = probe,
        Some((Step::Key(key), rest)) => {
            if !node.is_table() {
                *node = Value::Table(toml::Table::new());
            }
            let child = node
                .as_table_mut()
                .expect("a table")
                .entry(key.clone())
                .or_insert_with(|| Value::Table(toml::Table::new()));
            set(child, rest, probe);
        }
        Some((Step::First, rest)) => {
            let first = match node {
                Value::Array(items) if !items.is_empty() => items[0].clone(),
                _ => Value::Table(toml::Table::new()),
            };
            *node = Value::Array(vec![first]);
            set(&mut node.as_array_mut().expect("an array")[0], rest, probe);
        }
        Some((Step::Variant { tag, kind }, rest)) => {
            if node.get(tag.as_str()).and_then(Value::as_str) != Some(kind.as_str()) {
                let mut table = toml::Table::new();
                table.insert(tag.clone(), Value::String(kind.clone()));
                *node = Value::Table(table);
            }
            set(node, rest, probe);
        }
    }
}

fn table(entries: &[(&str, Value)]) -> Value {
    Value::Table(
        entries
            .iter()
            .map(|(key, value)| (key.to_string(), value.clone()))
            .collect(),
    )
}

fn join(key: &str, field: &str) -> String {
    if key.is_empty() {
        field.to_string()
    } else {
        format!("{key}.{field}")
    }
}

/// The texts between pairs of backticks.
pub fn backticked(text: &str) -> Vec<String> {
    text.split('`')
        .skip(1)
        .step_by(2)
        .map(str::to_string)
        .collect()
}

/// What the parser said about a document with a probe.
#[derive(Debug)]
enum Outcome {
    /// "unknown field `zz_unknown`, expected …": a table with these keys.
    Fields(Vec<String>),
    /// "missing field `kind`": a tagged table (with this tag) without its tag.
    Missing(String),
    /// "unknown variant `zz_unknown`, expected …": one of these names.
    Variants(Vec<String>),
    /// The document parsed: a table with free keys whose values may be integers.
    Parsed,
    /// "invalid type: integer `1`": a table with free keys that took the probe's key but not
    /// its value.
    ValueRefused,
    /// "invalid type: map, expected a sequence".
    Sequence,
    /// Any other value (a number, a string, a boolean, an untagged enum).
    Value,
    /// Anything else: the test cannot tell what the parser accepts.
    Unexplained(String),
}

fn classify(result: Result<(), String>) -> Outcome {
    let message = match result {
        Ok(()) => return Outcome::Parsed,
        Err(message) => message,
    };
    let after = |marker: &str| message.find(marker).map(|i| &message[i + marker.len()..]);
    if let Some(rest) = after(&format!("unknown field `{PROBE}`")) {
        // serde: ", expected one of `a`, `b`", ", expected `a` or `b`", ", there are no fields"
        return Outcome::Fields(backticked(rest));
    }
    if let Some(rest) = after(&format!("unknown variant `{PROBE}`")) {
        return Outcome::Variants(backticked(rest));
    }
    if let Some(rest) = after("missing field `") {
        return Outcome::Missing(rest.split('`').next().unwrap_or_default().to_string());
    }
    if message.contains("invalid type: integer `1`") {
        return Outcome::ValueRefused;
    }
    if message.contains("invalid type: map, expected a sequence") {
        return Outcome::Sequence;
    }
    if message.contains("invalid type: map, expected")
        || message.contains("did not match any variant of untagged enum")
    {
        return Outcome::Value;
    }
    Outcome::Unexplained(message)
}

/// A parser under probe: it parses `base` (a valid file) with probes put into it.
struct Prober<'a> {
    base: Value,
    parse: &'a dyn Fn(&str) -> Result<(), String>,
    keys: Keys,
}

impl Prober<'_> {
    fn probe(&self, steps: &[Step], probe: Value) -> Outcome {
        let mut document = self.base.clone();
        set(&mut document, steps, probe);
        let text = toml::to_string(&document).expect("a probed document writes as TOML");
        classify((self.parse)(&text))
    }

    fn accept(&mut self, key: &str) -> &mut Accepted {
        self.keys.entry(key.to_string()).or_default()
    }

    /// Harvests what the parser accepts at `key`, reached by `steps`, and below it.
    fn explore(&mut self, steps: &[Step], key: &str) {
        assert!(
            steps.len() <= 16,
            "`{key}`: tables nested too deep (a value that takes any table?)"
        );
        let with = |step: Step| {
            let mut steps = steps.to_vec();
            steps.push(step);
            steps
        };
        let probe = table(&[(PROBE, Value::Integer(1))]);
        match self.probe(steps, probe) {
            Outcome::Fields(fields) => {
                for field in fields {
                    let child = join(key, &field);
                    self.accept(&child);
                    self.explore(&with(Step::Key(field)), &child);
                }
            }
            Outcome::Missing(tag) => {
                let unknown_kind = table(&[(tag.as_str(), Value::String(PROBE.to_string()))]);
                let kinds = match self.probe(steps, unknown_kind) {
                    Outcome::Variants(kinds) => kinds,
                    other => panic!(
                        "`{key}`: the parser misses the field `{tag}`, but an unknown `{tag}` gives {other:?}"
                    ),
                };
                self.accept(&join(key, &tag))
                    .values
                    .extend(kinds.iter().cloned());
                let all: BTreeSet<String> = kinds.iter().cloned().collect();
                for kind in &kinds {
                    let probe = table(&[
                        (tag.as_str(), Value::String(kind.clone())),
                        (PROBE, Value::Integer(1)),
                    ]);
                    let fields = match self.probe(steps, probe) {
                        Outcome::Fields(fields) => fields,
                        other => panic!(
                            "`{key}` of kind `{kind}`: an unknown key gives {other:?}, not the list of keys"
                        ),
                    };
                    for field in fields {
                        let child = join(key, &field);
                        self.accept(&child).merge(&Accepted {
                            kinds: Some((
                                key.to_string(),
                                all.clone(),
                                BTreeSet::from([kind.clone()]),
                            )),
                            values: BTreeSet::new(),
                        });
                        let variant = with(Step::Variant {
                            tag: tag.clone(),
                            kind: kind.clone(),
                        });
                        let mut inner = variant;
                        inner.push(Step::Key(field));
                        self.explore(&inner, &child);
                    }
                }
            }
            Outcome::Variants(values) => self.accept(key).values.extend(values),
            Outcome::Parsed | Outcome::ValueRefused => {
                let child = join(key, FREE);
                self.accept(&child);
                self.explore(&with(Step::Key(PROBE.to_string())), &child);
            }
            Outcome::Sequence => self.explore(&with(Step::First), key),
            Outcome::Value => {}
            Outcome::Unexplained(message) => {
                panic!("cannot tell what the parser accepts at `{key}`: {message}")
            }
        }
    }
}

/// Every key the parser `parse` accepts, probed from each of the valid files `bases`
/// ((origin, text)); keys of maps have a [`FREE`] segment.
pub fn harvest(bases: &[(String, String)], parse: &dyn Fn(&str) -> Result<(), String>) -> Keys {
    let mut keys = Keys::new();
    for (origin, text) in bases {
        if let Err(message) = parse(text) {
            panic!("the starting file {origin} does not parse: {message}");
        }
        let base: Value = toml::from_str(text)
            .unwrap_or_else(|e| panic!("the starting file {origin} is not TOML: {e}"));
        let mut prober = Prober {
            base,
            parse,
            keys: Keys::new(),
        };
        prober.explore(&[], "");
        assert!(
            !prober.keys.is_empty(),
            "no key harvested from {origin}: the parser's messages changed?"
        );
        for (key, accepted) in prober.keys {
            keys.entry(key).or_default().merge(&accepted);
        }
    }
    keys
}

/// How the reference writes the keys of a map (a table with free keys).
pub enum Entries {
    /// One row with a placeholder (`constants.<name>`).
    Placeholder(&'static str),
    /// One row per name the validation accepts (`domain.sides.x_min`, …).
    Names(Vec<String>),
}

/// The harvested keys with the [`FREE`] segments written as the reference writes them:
/// `rules` gives, for the key of each map, how its entries are written. A map without a rule,
/// and a rule for no map, are problems (named with `rules_file`, where the rules are).
pub fn expand(keys: &Keys, rules: &[(&str, Entries)], rules_file: &str) -> (Keys, Vec<String>) {
    let mut problems = Vec::new();
    let mut pending: Vec<(String, Accepted)> =
        keys.iter().map(|(k, a)| (k.clone(), a.clone())).collect();
    let mut expanded = Keys::new();
    let mut used = BTreeSet::new();
    while let Some((key, accepted)) = pending.pop() {
        let segments: Vec<&str> = key.split('.').collect();
        let Some(free) = segments.iter().position(|s| *s == FREE) else {
            expanded.entry(key).or_default().merge(&accepted);
            continue;
        };
        let map = segments[..free].join(".");
        let rest = &segments[free + 1..];
        let Some((_, entries)) = rules.iter().find(|(prefix, _)| *prefix == map) else {
            let problem = format!(
                "the parser takes any key in the table `{map}` (a map): tell the test how the reference writes its entries, in the rules of {rules_file}"
            );
            if !problems.contains(&problem) {
                problems.push(problem);
            }
            continue;
        };
        used.insert(map.clone());
        let names: Vec<String> = match entries {
            Entries::Placeholder(placeholder) => vec![placeholder.to_string()],
            Entries::Names(names) => names.clone(),
        };
        for name in names {
            let mut key = segments[..free].to_vec();
            key.push(&name);
            key.extend_from_slice(rest);
            pending.push((key.join("."), accepted.clone()));
        }
    }
    for (prefix, _) in rules {
        if !used.contains(*prefix) {
            problems.push(format!(
                "the rules of {rules_file} name the map `{prefix}`, but the parser has no table of free keys there"
            ));
        }
    }
    (expanded, problems)
}

/// The names of a message's `(use a, b or c)` part, e.g. of "unknown side (use x_min, x_max,
/// y_min, y_max[, z_min, z_max])".
pub fn names_in_use_list(message: &str) -> Vec<String> {
    let start = message
        .rfind("(use ")
        .unwrap_or_else(|| panic!("no `(use …)` in the message `{message}`"))
        + "(use ".len();
    let end = message[start..]
        .find(')')
        .map_or(message.len(), |end| start + end);
    message[start..end]
        .split(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
        .filter(|word| !word.is_empty() && !["or", "and"].contains(word))
        .map(str::to_string)
        .collect()
}

// ---------------------------------------------------------------------------------------------
// Markdown
// ---------------------------------------------------------------------------------------------

/// A row of a Markdown table: its line (1-based) and its cells.
#[derive(Debug, Clone)]
pub struct Row {
    pub line: usize,
    pub cells: Vec<String>,
}

/// The cells of a table line (`|` escaped as `\|` stays in its cell).
fn cells(line: &str) -> Vec<String> {
    let line = line.trim();
    let line = line.strip_prefix('|').unwrap_or(line);
    let mut cells = Vec::new();
    let mut cell = String::new();
    let mut chars = line.chars();
    while let Some(c) = chars.next() {
        match c {
            '\\' => {
                cell.push(c);
                if let Some(next) = chars.next() {
                    cell.push(next);
                }
            }
            '|' => cells.push(std::mem::take(&mut cell).trim().to_string()),
            _ => cell.push(c),
        }
    }
    if !cell.trim().is_empty() {
        cells.push(cell.trim().to_string());
    }
    cells
}

/// A part of a Markdown page: outside code blocks, a heading (its line and text) or a table
/// (its header cells and rows).
#[derive(Debug)]
pub enum Block {
    Heading { line: usize, text: String },
    Table { header: Vec<String>, rows: Vec<Row> },
}

/// The headings and tables of a Markdown page, in order, outside code blocks.
pub fn blocks(text: &str) -> Vec<Block> {
    let mut blocks = Vec::new();
    let mut fence: Option<String> = None;
    let mut table: Option<(Vec<String>, Vec<Row>)> = None;
    for (index, line) in text.lines().enumerate() {
        let trimmed = line.trim_start();
        if let Some(open) = &fence {
            if trimmed.starts_with(open.as_str()) {
                fence = None;
            }
            continue;
        }
        let in_table = trimmed.starts_with('|');
        if !in_table {
            if let Some((header, rows)) = table.take() {
                blocks.push(Block::Table { header, rows });
            }
        }
        if trimmed.starts_with("```") || trimmed.starts_with("~~~") {
            fence = Some(trimmed[..3].to_string());
        } else if trimmed.starts_with('#') {
            blocks.push(Block::Heading {
                line: index + 1,
                text: trimmed.trim_start_matches('#').trim().to_string(),
            });
        } else if in_table {
            let row = cells(trimmed);
            match &mut table {
                None => table = Some((row, Vec::new())),
                // the delimiter row `|---|---|`
                Some(_) if row.iter().all(|c| c.chars().all(|c| "-: ".contains(c))) => {}
                Some((_, rows)) => rows.push(Row {
                    line: index + 1,
                    cells: row,
                }),
            }
        }
    }
    if let Some((header, rows)) = table {
        blocks.push(Block::Table { header, rows });
    }
    blocks
}

/// A row of a key table of a reference page.
#[derive(Debug, Clone)]
pub struct KeyRow {
    pub line: usize,
    pub key: String,
    /// The type column.
    pub kind: String,
}

/// The rows of the key tables (first column `key`) of the reference page `text`; a first cell
/// without exactly one key in backticks is a problem (named with `file`).
pub fn reference_keys(text: &str, file: &str) -> (Vec<KeyRow>, Vec<String>) {
    let mut rows = Vec::new();
    let mut problems = Vec::new();
    for block in blocks(text) {
        let Block::Table {
            header,
            rows: table,
        } = block
        else {
            continue;
        };
        if header.first().map(String::as_str) != Some("key") {
            continue;
        }
        for row in table {
            let first = row.cells.first().map(String::as_str).unwrap_or_default();
            match backticked(first).as_slice() {
                [key] => rows.push(KeyRow {
                    line: row.line,
                    key: key.clone(),
                    kind: row.cells.get(1).cloned().unwrap_or_default(),
                }),
                _ => problems.push(format!(
                    "{file}:{}: the key column `{first}` does not hold one key in backticks",
                    row.line
                )),
            }
        }
    }
    (rows, problems)
}

/// The problems of a reference page against the keys the parser accepts (`keys`, expanded):
/// (what the parser accepts and the page misses, what the page lists and the parser refuses).
/// Besides the keys themselves, the type column of a tag or of a key with fixed names must
/// list every name the parser accepts (as `"name"`) and no other, and the type column of a key
/// of a tagged table's variants must name (in backticks) every kind that has the key and no
/// kind that lacks it.
pub fn compare_keys(keys: &Keys, rows: &[KeyRow], file: &str) -> (Vec<String>, Vec<String>) {
    let mut missing = Vec::new();
    let mut refused = Vec::new();
    let mut listed: BTreeMap<&str, usize> = BTreeMap::new();
    for row in rows {
        if let Some(first) = listed.insert(&row.key, row.line) {
            refused.push(format!(
                "{file}:{}: `{}` is listed twice (also at line {first})",
                row.line, row.key
            ));
        }
    }
    for key in keys.keys() {
        if !listed.contains_key(key.as_str()) {
            missing.push(format!(
                "{file}: `{key}` is accepted by the parser but not listed in the key tables"
            ));
        }
    }
    for row in rows {
        let Some(accepted) = keys.get(&row.key) else {
            refused.push(format!(
                "{file}:{}: `{}` is listed, but the parser does not accept it",
                row.line, row.key
            ));
            continue;
        };
        let named: BTreeSet<String> = backticked(&row.kind).into_iter().collect();
        if !accepted.values.is_empty() {
            let quoted: BTreeSet<String> = named
                .iter()
                .filter_map(|n| n.strip_prefix('"')?.strip_suffix('"').map(str::to_string))
                .collect();
            for value in accepted.values.difference(&quoted) {
                missing.push(format!(
                    "{file}:{}: `{}` accepts `\"{value}\"`, which its type column does not list",
                    row.line, row.key
                ));
            }
            for value in quoted.difference(&accepted.values) {
                refused.push(format!(
                    "{file}:{}: the type column of `{}` lists `\"{value}\"`, which the parser refuses",
                    row.line, row.key
                ));
            }
        }
        if let Some((table, all, with)) = &accepted.kinds {
            for kind in with.difference(&named) {
                missing.push(format!(
                    "{file}:{}: `{}` is a key of the kind `{kind}` of `{table}`, which its type column does not name",
                    row.line, row.key
                ));
            }
            for kind in named.intersection(all) {
                if !with.contains(kind) {
                    refused.push(format!(
                        "{file}:{}: the type column of `{}` names the kind `{kind}` of `{table}`, which has no such key",
                        row.line, row.key
                    ));
                }
            }
        }
    }
    (missing, refused)
}

// ---------------------------------------------------------------------------------------------
// The command lines
// ---------------------------------------------------------------------------------------------

/// An argument of a command as its help shows it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ArgSpec {
    /// `--name` without the dashes.
    pub long: Option<String>,
    pub short: Option<char>,
    /// The value name of a flag that takes a value (`<ORDER>` → `ORDER`).
    pub value: Option<String>,
    /// The value name of a positional argument.
    pub positional: Option<String>,
}

/// A command (`["verify", "plan"]`) and its arguments.
#[derive(Debug, Clone)]
pub struct CommandSpec {
    pub path: Vec<String>,
    pub args: Vec<ArgSpec>,
}

impl CommandSpec {
    pub fn name(&self) -> String {
        self.path.join(" ")
    }
}

/// A row of a flag table of `cli.md`.
#[derive(Debug, Clone)]
pub struct FlagRow {
    pub line: usize,
    /// (name without dashes, value name).
    pub longs: Vec<(String, Option<String>)>,
    pub shorts: Vec<char>,
    pub positionals: Vec<String>,
}

/// The flag table of a command in `cli.md`: the first table with a `flag` column after a
/// heading that names the command in backticks (`` ### `verify plan` ``).
#[derive(Debug, Clone)]
pub struct Section {
    pub path: Vec<String>,
    pub line: usize,
    pub rows: Vec<FlagRow>,
}

fn flag_row(row: &Row) -> FlagRow {
    let mut flag = FlagRow {
        line: row.line,
        longs: Vec::new(),
        shorts: Vec::new(),
        positionals: Vec::new(),
    };
    for item in backticked(row.cells.first().map(String::as_str).unwrap_or_default()) {
        let mut words = item.split_whitespace();
        let first = words.next().unwrap_or_default();
        let value = words
            .next()
            .map(|v| v.trim_start_matches('<').trim_end_matches('>').to_string());
        if let Some(long) = first.strip_prefix("--") {
            flag.longs.push((long.to_string(), value));
        } else if let Some(short) = first.strip_prefix('-') {
            flag.shorts.extend(short.chars().next());
        } else if first.starts_with('<') {
            flag.positionals.push(
                first
                    .trim_start_matches('<')
                    .trim_end_matches('>')
                    .to_string(),
            );
        }
    }
    flag
}

/// The sections of `cli.md` of the commands of `program`.
pub fn cli_sections(text: &str, program: &str) -> Vec<Section> {
    let mut sections: Vec<Section> = Vec::new();
    let mut current: Option<Section> = None;
    for block in blocks(text) {
        match block {
            Block::Heading { line, text } => {
                sections.extend(current.take());
                // a heading that is one command in backticks, e.g. ### `verify plan`
                let named = backticked(&text);
                let path: Vec<String> = match named.as_slice() {
                    [command] if text == format!("`{command}`") => {
                        command.split_whitespace().map(str::to_string).collect()
                    }
                    _ => Vec::new(),
                };
                if path.first().map(String::as_str) == Some(program) {
                    current = Some(Section {
                        path,
                        line,
                        rows: Vec::new(),
                    });
                }
            }
            Block::Table { header, rows } => {
                if let Some(section) = &mut current {
                    if section.rows.is_empty() && header.first().map(String::as_str) == Some("flag")
                    {
                        section.rows = rows.iter().map(flag_row).collect();
                    }
                }
            }
        }
    }
    sections.extend(current);
    sections
}

/// The problems of the flag tables of `cli.md` (`file`) against the commands `specs`:
/// (what the commands have and the page misses, what the page lists and the commands lack).
pub fn compare_cli(
    specs: &[CommandSpec],
    sections: &[Section],
    file: &str,
) -> (Vec<String>, Vec<String>) {
    let mut missing = Vec::new();
    let mut unknown = Vec::new();
    for spec in specs {
        let name = spec.name();
        let Some(section) = sections.iter().find(|s| s.path == spec.path) else {
            missing.push(format!(
                "{file}: no section for `{name}` (a heading naming `{name}` in backticks, followed by a table whose first column is `flag`)"
            ));
            continue;
        };
        if section.rows.is_empty() {
            missing.push(format!(
                "{file}:{}: the section of `{name}` has no flag table (first column `flag`)",
                section.line
            ));
        }
        for arg in &spec.args {
            if let Some(positional) = &arg.positional {
                if !section
                    .rows
                    .iter()
                    .any(|r| r.positionals.contains(positional))
                {
                    missing.push(format!(
                        "{file}:{}: `{name}` takes the argument `<{positional}>`, which its table does not list",
                        section.line
                    ));
                }
                continue;
            }
            let Some(long) = &arg.long else {
                continue;
            };
            let Some((row, (_, value))) = section.rows.iter().find_map(|r| {
                r.longs
                    .iter()
                    .find(|(l, _)| l == long)
                    .map(|entry| (r, entry))
            }) else {
                missing.push(format!(
                    "{file}:{}: `{name}` has the flag `--{long}`, which its table does not list",
                    section.line
                ));
                continue;
            };
            if value != &arg.value {
                let show = |v: &Option<String>| match v {
                    Some(v) => format!("`--{long} <{v}>`"),
                    None => format!("`--{long}` without a value"),
                };
                missing.push(format!(
                    "{file}:{}: `{name}` shows {} in its help, the table {}",
                    row.line,
                    show(&arg.value),
                    show(value)
                ));
            }
            if let Some(short) = arg.short {
                if !row.shorts.contains(&short) {
                    missing.push(format!(
                        "{file}:{}: `--{long}` of `{name}` has the short form `-{short}`, which the table does not list",
                        row.line
                    ));
                }
            }
        }
        for row in &section.rows {
            for (long, _) in &row.longs {
                if !spec.args.iter().any(|a| a.long.as_ref() == Some(long)) {
                    unknown.push(format!(
                        "{file}:{}: `--{long}` is listed for `{name}`, which has no such flag",
                        row.line
                    ));
                }
            }
            for short in &row.shorts {
                if !spec.args.iter().any(|a| a.short == Some(*short)) {
                    unknown.push(format!(
                        "{file}:{}: `-{short}` is listed for `{name}`, which has no such flag",
                        row.line
                    ));
                }
            }
            for positional in &row.positionals {
                if !spec
                    .args
                    .iter()
                    .any(|a| a.positional.as_ref() == Some(positional))
                {
                    unknown.push(format!(
                        "{file}:{}: `<{positional}>` is listed for `{name}`, which takes no such argument",
                        row.line
                    ));
                }
            }
        }
    }
    for (i, section) in sections.iter().enumerate() {
        if let Some(first) = sections[..i].iter().find(|s| s.path == section.path) {
            unknown.push(format!(
                "{file}:{}: a second section for `{}` (the first is at line {})",
                section.line,
                section.path.join(" "),
                first.line
            ));
        }
        if !specs.iter().any(|s| s.path == section.path) {
            unknown.push(format!(
                "{file}:{}: the section names `{}`, which is no command",
                section.line,
                section.path.join(" ")
            ));
        }
    }
    (missing, unknown)
}

/// A command line of the guide that invokes the program.
#[derive(Debug, Clone)]
pub struct DocCommand {
    /// The page, relative to the workspace root.
    pub file: String,
    pub line: usize,
    /// The line as written (continuation lines joined).
    pub text: String,
    /// The arguments after the program name.
    pub args: Vec<String>,
}

/// The words of a shell command line, up to a comment, a pipe, a `;`, a `&` or a
/// redirection; quotes removed.
fn shell_words(line: &str) -> Vec<String> {
    let mut words = Vec::new();
    let mut word = String::new();
    let mut in_word = false;
    let mut quote: Option<char> = None;
    let mut chars = line.chars();
    while let Some(c) = chars.next() {
        if let Some(q) = quote {
            if c == q {
                quote = None;
            } else if c == '\\' && q == '"' {
                word.extend(chars.next());
            } else {
                word.push(c);
            }
            continue;
        }
        match c {
            '\'' | '"' => {
                quote = Some(c);
                in_word = true;
            }
            '\\' => {
                word.extend(chars.next());
                in_word = true;
            }
            '#' if !in_word => break,
            '|' | ';' | '&' => break,
            c if c.is_whitespace() => {
                if in_word {
                    words.push(std::mem::take(&mut word));
                    in_word = false;
                }
            }
            _ => {
                word.push(c);
                in_word = true;
            }
        }
    }
    if in_word {
        words.push(word);
    }
    // a redirection ends the command
    if let Some(end) = words.iter().position(|w| {
        w.starts_with('>') || w.starts_with("1>") || w.starts_with("2>") || w.starts_with("&>")
    }) {
        words.truncate(end);
    }
    words
}

/// Why a command line of the guide is not checked: it holds a placeholder. A placeholder is a
/// word with `$` (a shell variable), `<…>` (`<CASE>`), `[…]` (an optional part), `…` or
/// `...`, or a word in capitals (`NAME`, `FILE`, `L`, `T/2`: a run of letters, digits and `_`
/// with a capital and no small letter; in a flag, only its value after `=` counts, so `-V`
/// is no placeholder).
pub fn placeholder(args: &[String]) -> Option<String> {
    args.iter()
        .find(|word| {
            if ["$", "<", ">", "[", "]", "…", "..."]
                .iter()
                .any(|mark| word.contains(mark))
            {
                return true;
            }
            let value = if word.starts_with('-') {
                word.split_once('=').map_or("", |(_, value)| value)
            } else {
                word.as_str()
            };
            value
                .split(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
                .any(|run| {
                    run.chars().any(|c| c.is_ascii_uppercase())
                        && !run.chars().any(|c| c.is_ascii_lowercase())
                })
        })
        .cloned()
}

/// `README.md` and every page under `docs/`, relative to `root`, sorted.
pub fn guide_pages(root: &Path) -> Vec<String> {
    fn walk(folder: &Path, root: &Path, pages: &mut Vec<String>) {
        let entries = std::fs::read_dir(folder)
            .unwrap_or_else(|e| panic!("cannot list {}: {e}", folder.display()));
        for entry in entries {
            let path = entry.expect("a folder entry").path();
            if path.is_dir() {
                walk(&path, root, pages);
            } else if path.extension().is_some_and(|e| e == "md") {
                let relative = path.strip_prefix(root).expect("under the root");
                pages.push(relative.to_string_lossy().replace('\\', "/"));
            }
        }
    }
    let mut pages = vec!["README.md".to_string()];
    walk(&root.join("docs"), root, &mut pages);
    pages.sort();
    pages
}

/// The arguments of `words` if they invoke `program`: `cargo run [OPTIONS] -p PROGRAM [--
/// ARGS]` (not an `--example`, `--bin`, `--test` or `--bench` of the package) in any code
/// block, or `PROGRAM ARGS` (also `target/release/PROGRAM`) at the start of a line of a
/// `sh`/`bash`/`shell`/`console` block.
fn invocation(words: &[String], program: &str, shell: bool) -> Option<Vec<String>> {
    let words: &[String] = match words.first() {
        Some(prompt) if prompt == "$" => &words[1..],
        _ => words,
    };
    if words.len() >= 2 && words[0] == "cargo" && words[1] == "run" {
        let end = words.iter().position(|w| w == "--").unwrap_or(words.len());
        let options = &words[2..end];
        let package = options.iter().enumerate().find_map(|(i, w)| {
            if w == "-p" || w == "--package" {
                options.get(i + 1).map(String::as_str)
            } else {
                w.strip_prefix("--package=")
                    .or_else(|| w.strip_prefix("-p"))
            }
        });
        let other_target = options.iter().any(|w| {
            ["--example", "--bin", "--test", "--bench"]
                .iter()
                .any(|o| w == o || w.starts_with(&format!("{o}=")))
        });
        if package != Some(program) || other_target {
            return None;
        }
        return Some(words.get(end + 1..).unwrap_or_default().to_vec());
    }
    let first = words.first()?.trim_start_matches("./");
    let binary = [
        program.to_string(),
        format!("target/release/{program}"),
        format!("target/debug/{program}"),
    ];
    (shell && binary.iter().any(|b| b == first)).then(|| words[1..].to_vec())
}

/// The command lines of the guide's code blocks that invoke `program` (see [`invocation`]):
/// those to check, and those skipped because they hold a [`placeholder`] (with it).
pub fn doc_commands(root: &Path, program: &str) -> (Vec<DocCommand>, Vec<(DocCommand, String)>) {
    let mut checked = Vec::new();
    let mut skipped = Vec::new();
    for file in guide_pages(root) {
        let text = read(root, &file);
        let mut fence: Option<(String, String)> = None;
        let mut pending: Option<(usize, String)> = None;
        for (index, line) in text.lines().enumerate() {
            let trimmed = line.trim();
            let Some((open, language)) = fence.clone() else {
                if trimmed.starts_with("```") || trimmed.starts_with("~~~") {
                    let language = trimmed[3..]
                        .trim_start_matches(['`', '~'])
                        .split(|c: char| c.is_whitespace() || c == ',' || c == '{')
                        .next()
                        .unwrap_or_default()
                        .to_lowercase();
                    fence = Some((trimmed[..3].to_string(), language));
                }
                continue;
            };
            if trimmed.starts_with(&open) {
                fence = None;
                pending = None;
                continue;
            }
            let shell = ["sh", "bash", "shell", "console"].contains(&language.as_str());
            let (start, mut joined) = pending.take().unwrap_or((index + 1, String::new()));
            if let Some(head) = trimmed.strip_suffix('\\') {
                joined.push_str(head);
                joined.push(' ');
                pending = Some((start, joined));
                continue;
            }
            joined.push_str(trimmed);
            let words = shell_words(&joined);
            let Some(args) = invocation(&words, program, shell) else {
                continue;
            };
            let command = DocCommand {
                file: file.clone(),
                line: start,
                text: joined,
                args,
            };
            match placeholder(&command.args) {
                Some(word) => skipped.push((command, word)),
                None => checked.push(command),
            }
        }
    }
    (checked, skipped)
}

/// The guide's command line `args` (after the program name) found among `commands`, or a
/// message saying it is gone from the guide (the list of cheap commands a test runs must follow
/// the pages).
pub fn find_doc_command<'a>(
    commands: &'a [DocCommand],
    args: &str,
) -> Result<&'a DocCommand, String> {
    commands
        .iter()
        .find(|command| command.args.join(" ") == args)
        .ok_or_else(|| {
            format!("`{args}` is no longer a command line of the guide: update the list of cheap commands")
        })
}

/// The arguments of a guide command with its output redirected into `scratch`: the value of
/// `--out` or `--manifest` becomes a path under `scratch` with the same file name, and a command
/// without `--out` gets `--out scratch/<stem of its first argument>` (so that a run never writes
/// into the checkout, and commands on the same input share their folder as on the page).
pub fn redirected_args(args: &[String], scratch: &Path) -> Vec<String> {
    let mut redirected = Vec::with_capacity(args.len() + 2);
    let mut has_out = false;
    let mut words = args.iter();
    while let Some(word) = words.next() {
        redirected.push(word.clone());
        if word == "--out" || word == "--manifest" {
            has_out |= word == "--out";
            if let Some(value) = words.next() {
                let name = Path::new(value).file_name().unwrap_or_default();
                redirected.push(scratch.join(name).display().to_string());
            }
        }
    }
    if !has_out {
        let stem = args
            .iter()
            .find(|word| !word.starts_with('-'))
            .and_then(|word| Path::new(word).file_stem())
            .map(|stem| stem.to_string_lossy().into_owned())
            .unwrap_or_else(|| "default".into());
        redirected.push("--out".into());
        redirected.push(scratch.join(stem).display().to_string());
    }
    redirected
}

/// Runs the guide's command lines `cheap` (arguments after the program name, exactly as on the
/// page, each with the exit statuses it may end with) with `binary` in the workspace root, in
/// order, each with its output redirected into one scratch folder ([`redirected_args`]);
/// returns one message per command that is gone from the guide or exits otherwise.
pub fn run_cheap_commands(
    root: &Path,
    program: &str,
    binary: &str,
    cheap: &[(&str, &[i32])],
) -> Vec<String> {
    let (commands, _) = doc_commands(root, program);
    let scratch = tempfile::tempdir().expect("a temporary folder");
    let mut problems = Vec::new();
    for &(args, accepted) in cheap {
        let command = match find_doc_command(&commands, args) {
            Ok(command) => command,
            Err(problem) => {
                problems.push(problem);
                continue;
            }
        };
        let argv = redirected_args(&command.args, scratch.path());
        let output = std::process::Command::new(binary)
            .args(&argv)
            .current_dir(root)
            .output()
            .unwrap_or_else(|error| panic!("`{program}` starts: {error}"));
        let status = output.status.code().unwrap_or(-1);
        eprintln!(
            "{}:{}: `{program} {args}` exited with {status}",
            command.file, command.line
        );
        if !accepted.contains(&status) {
            problems.push(format!(
                "{}:{}: `{program} {}` exited with {status}:\n{}",
                command.file,
                command.line,
                argv.join(" "),
                String::from_utf8_lossy(&output.stderr).trim()
            ));
        }
    }
    problems
}
