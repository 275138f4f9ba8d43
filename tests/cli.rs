//! End-to-end tests of the `verify` command line: reports are written, bad input gets a clear
//! error and a non-zero exit status.

use crate::process;

use process::{closed_pipe, full_disk, output_within_a_minute};
use std::process::Command;

fn verify() -> Command {
    Command::new(env!("CARGO_BIN_EXE_verify"))
}

#[test]
fn verify_writes_csv_json_and_svg_reports() {
    let out = std::env::temp_dir().join(format!("verify-cli-{}", std::process::id()));
    let status = verify()
        .args(["--order", "1", "--studies", "h,diagonal", "--out"])
        .arg(&out)
        .env("CI", "1")
        .output()
        .unwrap();
    assert!(
        status.status.success(),
        "{}",
        String::from_utf8_lossy(&status.stderr)
    );
    let csv = std::fs::read_to_string(out.join("errors.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 8, "header + 2 studies × 4 runs");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(json["case"], "zones2d");
    assert_eq!(json["studies"].as_array().unwrap().len(), 2);
    let svg = std::fs::read_to_string(out.join("h-l1.svg")).unwrap();
    assert!(svg.contains("<svg") && svg.contains("damage gradient"));
    // the least-squares rates carry their standard error on the terminal; rates.csv, report.md
    // and tables.tex are written too, with the total error of every run of errors.csv
    let stdout = String::from_utf8_lossy(&status.stdout);
    assert!(stdout.contains("(SE)"), "{stdout}");
    assert!(stdout.contains("\nverdict: PASS"), "{stdout}");
    let rates = std::fs::read_to_string(out.join("rates.csv")).unwrap();
    assert_eq!(
        rates.lines().count(),
        1 + 2 * 6,
        "header + 2 studies × 6 components"
    );
    assert!(rates
        .lines()
        .next()
        .unwrap()
        .contains("standard_error,ci95_low,ci95_high,drifting"));
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    let tex = std::fs::read_to_string(out.join("tables.tex")).unwrap();
    let mut reader = csv::Reader::from_reader(csv.as_bytes());
    let total = reader
        .headers()
        .unwrap()
        .iter()
        .position(|h| h == "total")
        .unwrap();
    for record in reader.records() {
        let value: f64 = record.unwrap()[total].parse().unwrap();
        let printed = format!("{value:.3e}");
        assert!(md.contains(&format!("| {printed} |")), "{printed}: {md}");
        assert!(tex.contains(&format!("& {printed} &")), "{printed}: {tex}");
    }
    assert!(md.contains("](h-l1.svg)") && md.contains("](diagonal-l1.svg)"));
    // no temporary file left behind
    for entry in std::fs::read_dir(&out).unwrap() {
        let name = entry.unwrap().file_name().into_string().unwrap();
        assert!(!name.contains("tmp"), "leftover temporary file {name}");
    }
    std::fs::remove_dir_all(&out).ok();
}

#[test]
fn verify_k_study_reports_newton_statistics_and_no_nan() {
    let out = std::env::temp_dir().join(format!("verify-cli-k-{}", std::process::id()));
    let output = verify()
        .args(["--order", "1", "--levels", "2", "--studies", "h,k", "--out"])
        .arg(&out)
        .env("CI", "1")
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&output.stdout);
    // two levels give one pairwise rate and no fit: the reports are written, but nothing is
    // certified (exit status 3)
    assert_eq!(
        output.status.code(),
        Some(3),
        "{stdout}\n{}",
        String::from_utf8_lossy(&output.stderr)
    );
    assert!(stdout.contains("\nverdict: DRIFTING"), "{stdout}");
    let csv = std::fs::read_to_string(out.join("errors.csv")).unwrap();
    let json_text = std::fs::read_to_string(out.join("summary.json")).unwrap();
    for (name, text) in [
        ("stdout", stdout.as_ref()),
        ("errors.csv", csv.as_str()),
        ("summary.json", json_text.as_str()),
    ] {
        let lower = text.to_lowercase();
        assert!(
            !lower.contains("nan") && !lower.contains("inf"),
            "{name} has a NaN or inf:\n{text}"
        );
    }
    // terminal: the per-run columns show the Newton iterations per step, and the k-study
    // prints no rates for the velocity error, which has no value against a discrete reference
    assert!(stdout.contains("Newton m/M"), "{stdout}");
    let k_table = &stdout[stdout.find("k-study").expect("k-study table")..];
    assert!(!k_table.contains("velocity"), "{k_table}");

    // errors.csv: the velocity cell of a k-study row is an em dash, a number elsewhere
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let column = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), 4, "2 studies × 2 runs:\n{csv}");
    for row in &rows {
        let velocity = row[column("velocity")];
        match row[column("study")] {
            "k" => assert_eq!(velocity, "—"),
            _ => assert!(velocity.parse::<f64>().unwrap() > 0.0),
        }
        let mean: f64 = row[column("mean_newton_iterations")].parse().unwrap();
        let max: usize = row[column("max_newton_iterations")].parse().unwrap();
        assert!(mean >= 1.0 && max as f64 >= mean, "{row:?}");
    }

    // summary.json: Newton iterations of (5.1) per step, and the slowest step's history
    let json: serde_json::Value = serde_json::from_str(&json_text).unwrap();
    let tolerance = contact_damage::scheme::velocity::VelocitySettings::default().tolerance;
    let studies = json["studies"].as_array().unwrap();
    assert_eq!(studies.len(), 2);
    for study in studies {
        let k_study = study["kind"] == "k";
        for run in study["runs"].as_array().unwrap() {
            let stats = &run["stats"];
            let mean = stats["mean_newton_iterations"].as_f64().unwrap();
            let max = stats["max_newton_iterations"].as_u64().unwrap();
            let total = stats["newton_iterations"].as_u64().unwrap();
            let steps = run["steps"].as_u64().unwrap();
            assert!(mean >= 1.0 && max as f64 >= mean, "{stats}");
            assert!(
                (mean - total as f64 / steps as f64).abs() < 1e-12,
                "{stats}"
            );
            let history = stats["slowest_newton_history"].as_array().unwrap();
            assert_eq!(history.len() as u64, max, "{stats}");
            let last = history.last().unwrap().as_f64().unwrap();
            assert!(last <= tolerance, "{stats}");
            assert_eq!(run["errors"]["velocity"].is_null(), k_study, "{run}");
        }
        let velocity = study["rates"]
            .as_array()
            .unwrap()
            .iter()
            .find(|r| r["component"] == "velocity")
            .unwrap();
        assert!(velocity["pass"].is_null());
        if k_study {
            assert!(velocity["least_squares"].is_null(), "{velocity}");
            assert!(velocity["pairwise"][0].is_null(), "{velocity}");
        }
    }
    std::fs::remove_dir_all(&out).ok();
}

#[test]
fn verify_rejects_a_bad_case_file_with_its_name_and_key() {
    let dir = std::env::temp_dir().join(format!("verify-bad-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let text = include_str!("../verification/zones2d.toml")
        .replace("\"-(0.1 + 0.1*t)*x^2*(1-y)\"", "\"-(0.1 + 0.1*t)*w^2\"");
    let path = dir.join("broken.toml");
    std::fs::write(&path, text).unwrap();
    let output = verify().arg("--case").arg(&path).output().unwrap();
    assert_eq!(output.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("broken.toml")
            && stderr.contains("exact.u[1]")
            && stderr.contains("unknown variable"),
        "{stderr}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn verify_rejects_an_unknown_order() {
    let output = verify().args(["--order", "3"]).output().unwrap();
    assert_eq!(output.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&output.stderr).contains("--order must be 1 or 2"));
}

/// Runs `verify` with `args` (then `--out out`) and checks that it was refused before any work:
/// exit status 2, no study table on stdout, no output folder. Returns stderr.
fn refused(args: &[&str], out: &std::path::Path) -> String {
    let existed = out.exists();
    let output = verify().args(args).arg("--out").arg(out).output().unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
    assert_eq!(output.status.code(), Some(2), "{stderr}");
    assert!(
        output.stdout.is_empty(),
        "{}",
        String::from_utf8_lossy(&output.stdout)
    );
    assert_eq!(out.exists(), existed, "{args:?}: output folder created");
    stderr
}

/// A fresh scratch folder for one test of this file.
fn scratch(name: &str) -> std::path::PathBuf {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("verify-cli-{name}"));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn verify_refuses_too_many_threads_before_any_work() {
    let out = scratch("threads").join("out");
    for threads in ["10000", "0"] {
        let stderr = refused(&["--threads", threads], &out);
        assert!(
            stderr.contains(&format!("--threads {threads}")) && stderr.contains("1 ..= "),
            "{stderr}"
        );
    }
}

#[test]
fn verify_refuses_an_unknown_study_before_solving() {
    let out = scratch("studies").join("out");
    let stderr = refused(&["--studies", "h,foo"], &out);
    assert!(
        stderr.contains("--studies") && stderr.contains("`foo`"),
        "{stderr}"
    );
}

#[test]
fn verify_refuses_an_out_that_is_no_writable_folder_before_solving() {
    let dir = scratch("out");
    let file = dir.join("report.txt");
    std::fs::write(&file, "mine\n").unwrap();
    for (out, reason) in [
        (file.clone(), "exists and is not a folder"),
        (file.join("sub"), "is a file, not a folder"),
    ] {
        let stderr = refused(&["--levels", "2"], &out);
        assert!(
            stderr.contains("--out")
                && stderr.contains(&out.display().to_string())
                && stderr.contains(reason),
            "{stderr}"
        );
    }
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "mine\n");

    // a folder nobody may create a file in, root included: /proc (the kernel refuses new
    // files there; the probe's create_new fails with ENOENT)
    #[cfg(target_os = "linux")]
    {
        let proc = std::path::Path::new("/proc");
        assert!(proc.is_dir(), "/proc is not mounted");
        let stderr = refused(&["--levels", "2"], proc);
        assert!(
            stderr.contains("--out `/proc`") && stderr.contains("cannot write into the folder"),
            "{stderr}"
        );
    }
    // a folder without write permission, for a user the permissions bind (root may write
    // anyway: the /proc case above covers the refusal for root)
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let locked = dir.join("locked");
        std::fs::create_dir_all(&locked).unwrap();
        std::fs::set_permissions(&locked, std::fs::Permissions::from_mode(0o555)).unwrap();
        if std::fs::write(locked.join("probe"), "").is_ok() {
            eprintln!("read-only folder not checked: this user may write into a 0o555 folder");
        } else {
            let stderr = refused(&["--levels", "2"], &locked);
            assert!(
                stderr.contains("--out") && stderr.contains("cannot write into the folder"),
                "{stderr}"
            );
        }
        std::fs::set_permissions(&locked, std::fs::Permissions::from_mode(0o755)).unwrap();
    }
}

/// A case file with zones2d's text changed by `from → to`, written into `dir`.
fn changed_zones2d(dir: &std::path::Path, from: &str, to: &str) -> std::path::PathBuf {
    let text = include_str!("../verification/zones2d.toml");
    assert!(text.contains(from), "{from}");
    let path = dir.join("changed.toml");
    std::fs::write(&path, text.replace(from, to)).unwrap();
    path
}

#[test]
fn verify_refuses_a_domain_bound_that_is_not_finite_naming_the_key() {
    let dir = scratch("domain");
    let case = changed_zones2d(&dir, "upper = [1.0, 1.0]", "upper = [nan, 1.0]");
    let stderr = refused(&["--case", case.to_str().unwrap()], &dir.join("out"));
    assert!(
        stderr.contains("changed.toml") && stderr.contains("domain.lower/upper"),
        "{stderr}"
    );
    assert!(!stderr.contains("exact.beta"), "{stderr}");
}

#[test]
fn verify_refuses_fewer_than_two_levels_as_an_option_error() {
    let out = scratch("levels").join("out");
    for levels in ["0", "1"] {
        let stderr = refused(&["--levels", levels], &out);
        assert!(stderr.contains("--levels"), "{stderr}");
        assert!(!stderr.contains("case"), "{stderr}");
    }
}

/// A contact stiffness far above the stability limit of the explicit normal compliance makes the
/// contact pressures grow out of scale; the error says why (the limit, the level, the key to change) and keeps
/// the solver's message as the symptom.
#[test]
fn verify_names_the_stability_limit_when_a_stiff_case_fails() {
    let dir = scratch("stiff");
    // far above the stability limit, within the scale of double precision (≤ 1e150)
    let case = changed_zones2d(&dir, "stiffness = 10.0", "stiffness = 1e100");
    let output = verify()
        .args([
            "--case",
            case.to_str().unwrap(),
            "--studies",
            "h",
            "--levels",
            "2",
        ])
        .arg("--out")
        .arg(dir.join("out"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(2), "{stderr}");
    for part in [
        "changed.toml",
        "stability limit",
        "laws.contact.stiffness",
        "4 cells and 2 steps",
    ] {
        assert!(stderr.contains(part), "`{part}` missing in {stderr}");
    }
}

/// A manufactured field with a pole inside the domain, or a displacement that vanishes, is an
/// input error naming the key, not a FAIL verdict with errors of 10³ or NaN rates.
#[test]
fn verify_refuses_a_singular_or_vanishing_manufactured_displacement() {
    let dir = scratch("singular");
    let u =
        "u = [\"0.05*x*y*(1+t) + 0.5*t*max(0, x - x_slip)^4*(1+y)\", \"-(0.1 + 0.1*t)*x^2*(1-y)\"]";
    for (to, key, reason) in [
        (
            "u = [\"0.05*x*y*(1+t) + 0.5*t*max(0, x - x_slip)^4*(1+y)\", \"0.1*x/(y - 0.3)\"]",
            "exact.u[1]",
            "singular or not resolved",
        ),
        (
            "u = [\"0\", \"0\"]",
            "exact.u",
            "vanishes at every sample point",
        ),
    ] {
        let case = changed_zones2d(&dir, u, to);
        let stderr = refused(&["--case", case.to_str().unwrap()], &dir.join("out"));
        assert!(
            stderr.contains("changed.toml") && stderr.contains(key) && stderr.contains(reason),
            "{stderr}"
        );
    }
}

/// Studies whose levels cannot fit in memory are refused before the first solve, with the
/// estimate and the limit, never aborted in an allocation.
#[test]
fn verify_refuses_studies_too_large_for_the_memory_before_solving() {
    let dir = scratch("memory");
    let case = changed_zones2d(
        &dir,
        "h = { cells = [4, 8, 16, 32]",
        "h = { cells = [4, 8, 16, 1000000000]",
    );
    let stderr = refused(&["--case", case.to_str().unwrap()], &dir.join("out"));
    assert!(
        stderr.contains("h study") && stderr.contains("GiB") && stderr.contains("--memory-limit"),
        "{stderr}"
    );
    let stderr = refused(&["--memory-limit", "0.0001"], &dir.join("out"));
    assert!(
        stderr.contains("MiB") && stderr.contains("above the limit"),
        "{stderr}"
    );
    let stderr = refused(&["--memory-limit=-1"], &dir.join("out"));
    assert!(stderr.contains("--memory-limit -1"), "{stderr}");
}

#[test]
fn verify_baseline_regenerates_the_baseline_and_lists_the_errors_that_moved() {
    // a copy of the committed baseline of zones2d at l = 1, one error changed by hand
    let scratch = tempfile::tempdir().unwrap();
    let committed =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../reports/zones2d/l1");
    let copy = scratch.path().join("zones2d/l1");
    std::fs::create_dir_all(&copy).unwrap();
    let csv = std::fs::read_to_string(committed.join("errors.csv")).unwrap();
    let mut lines: Vec<String> = csv.lines().map(String::from).collect();
    let header: Vec<&str> = lines[0].split(',').collect();
    let column = header.iter().position(|h| *h == "damage").unwrap();
    let mut cells: Vec<String> = lines[2].split(',').map(String::from).collect();
    let (study, level, steps) = (cells[1].clone(), cells[4].clone(), cells[8].clone());
    let original: f64 = cells[column].parse().unwrap();
    cells[column] = (original * 1.001).to_string();
    lines[2] = cells.join(",");
    std::fs::write(copy.join("errors.csv"), lines.join("\n") + "\n").unwrap();

    let output = verify()
        .args(["baseline", "--case", "zones2d", "--order", "1", "--reports"])
        .arg(scratch.path())
        .env("CI", "1")
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        output.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&output.stderr)
    );
    // the changed value is listed as moved back to the computed one, and only it
    assert!(
        stdout.contains("12 runs compared (0 removed, 0 added)")
            && stdout.contains("1 errors moved"),
        "{stdout}"
    );
    let moved = format!("{study}-study level {level}, {steps} steps: damage");
    assert!(stdout.contains(&moved), "{moved} not in\n{stdout}");
    // the regenerated errors are those of the committed baseline (to the pinned tolerance of
    // the CI rate tests: KKT residuals and wall times may differ between machines)
    let regenerated = std::fs::read_to_string(copy.join("errors.csv")).unwrap();
    let components = [
        "displacement",
        "difference_quotient",
        "damage",
        "damage_gradient",
        "total",
    ];
    let values = |text: &str| -> Vec<f64> {
        let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
        text.lines()
            .skip(1)
            .flat_map(|line| {
                let cells: Vec<String> = line.split(',').map(String::from).collect();
                components
                    .iter()
                    .map(|name| {
                        let at = header.iter().position(|h| h == name).unwrap();
                        cells[at].parse::<f64>().unwrap()
                    })
                    .collect::<Vec<_>>()
            })
            .collect()
    };
    let (new, old) = (values(&regenerated), values(&csv));
    assert_eq!(new.len(), old.len());
    for (new, old) in new.iter().zip(&old) {
        assert!((new - old).abs() <= 1e-8 * old.abs(), "{new} against {old}");
    }
    for name in [
        "summary.json",
        "rates.csv",
        "report.md",
        "h-l1.svg",
        "manifest.json",
    ] {
        assert!(copy.join(name).exists(), "{name} not written");
    }
}

/// Runs `verify args` with standard output `stdout`; returns the status and stderr.
fn verify_into(args: &[&std::ffi::OsStr], stdout: std::process::Stdio) -> (Option<i32>, String) {
    let output = verify()
        .args(args)
        .env("CI", "1")
        .stdout(stdout)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap()
        .wait_with_output()
        .unwrap();
    (
        output.status.code(),
        String::from_utf8_lossy(&output.stderr).into_owned(),
    )
}

/// Two cheap commands that write to standard output: `--help`, and `plan` of a small case
/// into a fresh folder under `dir` named `name`.
fn cheap_commands(dir: &std::path::Path, name: &str) -> Vec<Vec<std::ffi::OsString>> {
    let out = dir.join(name);
    vec![
        vec!["--help".into()],
        vec![
            "plan".into(),
            "--case".into(),
            "slip2d".into(),
            "--levels".into(),
            "2".into(),
            "--out".into(),
            out.into_os_string(),
        ],
    ]
}

#[test]
fn a_full_standard_output_is_an_error_naming_it_not_a_panic() {
    let dir = scratch("dev-full");
    for args in cheap_commands(&dir, "plan") {
        let args: Vec<&std::ffi::OsStr> = args.iter().map(|a| a.as_os_str()).collect();
        let (status, stderr) = verify_into(&args, full_disk());
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
        assert_eq!(status, Some(2), "{args:?}: {stderr}");
        assert!(
            stderr.contains("standard output") && stderr.contains("No space left on device"),
            "{args:?}: {stderr}"
        );
    }
}

#[test]
fn a_closed_standard_output_ends_quietly_with_status_141() {
    let dir = scratch("closed-pipe");
    for args in cheap_commands(&dir, "plan") {
        let args: Vec<&std::ffi::OsStr> = args.iter().map(|a| a.as_os_str()).collect();
        let (status, stderr) = verify_into(&args, closed_pipe());
        assert_eq!(status, Some(141), "{args:?}: {stderr}");
        assert!(stderr.is_empty(), "{args:?}: {stderr}");
    }
}

/// Runs `verify args` (with `CI` set); returns the status, stdout and stderr.
fn verify_args(args: &[&std::ffi::OsStr]) -> (Option<i32>, String, String) {
    let output = verify().args(args).env("CI", "1").output().unwrap();
    (
        output.status.code(),
        String::from_utf8_lossy(&output.stdout).into_owned(),
        String::from_utf8_lossy(&output.stderr).into_owned(),
    )
}

#[test]
fn no_command_replaces_a_report_it_did_not_write() {
    let dir = scratch("user-files");
    let out = dir.join("out");
    std::fs::create_dir_all(&out).unwrap();
    let mine = [("report.md", "my notes\n"), ("errors.csv", "my,table\n")];
    for (name, text) in mine {
        std::fs::write(out.join(name), text).unwrap();
    }
    let study = |out: &std::path::Path, extra: &[&str]| {
        let mut args: Vec<std::ffi::OsString> = ["--levels", "2", "--studies", "h", "--out"]
            .map(Into::into)
            .to_vec();
        args.push(out.as_os_str().to_owned());
        args.extend(extra.iter().map(Into::into));
        let args: Vec<&std::ffi::OsStr> = args.iter().map(|a| a.as_os_str()).collect();
        verify_args(&args)
    };
    // a plain run: refused before any work, naming both files, which are kept
    let (status, stdout, stderr) = study(&out, &[]);
    assert_eq!(status, Some(2), "{stdout}\n{stderr}");
    for (name, text) in mine {
        let path = out.join(name).display().to_string();
        assert!(stderr.contains(&format!("`{path}`")), "{path}: {stderr}");
        assert_eq!(std::fs::read_to_string(out.join(name)).unwrap(), text);
    }
    assert!(stderr.contains("--overwrite"), "{stderr}");
    assert!(!out.join("manifest.json").exists() && !out.join("runs").exists());

    // `plan` refuses a manifest of the user
    let planned = dir.join("planned");
    std::fs::create_dir_all(&planned).unwrap();
    std::fs::write(planned.join("manifest.json"), "{}\n").unwrap();
    let plan = |extra: &[&str]| {
        let mut args: Vec<std::ffi::OsString> =
            ["plan", "--levels", "2", "--studies", "h", "--out"]
                .map(Into::into)
                .to_vec();
        args.push(planned.as_os_str().to_owned());
        args.extend(extra.iter().map(Into::into));
        let args: Vec<&std::ffi::OsStr> = args.iter().map(|a| a.as_os_str()).collect();
        verify_args(&args)
    };
    let (status, _, stderr) = plan(&[]);
    assert_eq!(status, Some(2), "{stderr}");
    assert!(stderr.contains("manifest.json`"), "{stderr}");
    assert_eq!(
        std::fs::read_to_string(planned.join("manifest.json")).unwrap(),
        "{}\n"
    );
    let (status, _, stderr) = plan(&["--overwrite"]);
    assert_eq!(status, Some(0), "{stderr}");
    // a manifest verify wrote may be written again
    let (status, _, stderr) = plan(&[]);
    assert_eq!(status, Some(0), "{stderr}");

    // `merge` refuses a report of the user beside the manifest, before writing any report
    let manifest = planned.join("manifest.json");
    let (status, _, stderr) = verify_args(&[
        "run".as_ref(),
        "--manifest".as_ref(),
        manifest.as_os_str(),
        "--shard".as_ref(),
        "0/1".as_ref(),
    ]);
    assert_eq!(status, Some(0), "{stderr}");
    std::fs::write(planned.join("report.md"), "my notes\n").unwrap();
    let merge = |extra: &[&str]| {
        let mut args: Vec<std::ffi::OsString> = vec!["merge".into(), "--manifest".into()];
        args.push(manifest.as_os_str().to_owned());
        args.extend(extra.iter().map(Into::into));
        let args: Vec<&std::ffi::OsStr> = args.iter().map(|a| a.as_os_str()).collect();
        verify_args(&args)
    };
    let (status, _, stderr) = merge(&[]);
    assert_eq!(status, Some(2), "{stderr}");
    assert!(stderr.contains("report.md`"), "{stderr}");
    assert_eq!(
        std::fs::read_to_string(planned.join("report.md")).unwrap(),
        "my notes\n"
    );
    assert!(!planned.join("errors.csv").exists());
    // (two levels are too few to certify a rate: DRIFTING, status 3)
    let (status, _, stderr) = merge(&["--overwrite"]);
    assert_eq!(status, Some(3), "{stderr}");
    assert_ne!(
        std::fs::read_to_string(planned.join("report.md")).unwrap(),
        "my notes\n"
    );

    // a plain run into a fresh folder, run again, replaces its own reports; a report edited
    // since is the user's and refused
    let fresh = dir.join("fresh");
    for _ in 0..2 {
        let (status, stdout, stderr) = study(&fresh, &[]);
        assert_eq!(status, Some(3), "{stdout}\n{stderr}");
    }
    std::fs::write(fresh.join("tables.tex"), "% my edits\n").unwrap();
    let (status, _, stderr) = study(&fresh, &[]);
    assert_eq!(status, Some(2), "{stderr}");
    assert!(stderr.contains("tables.tex`"), "{stderr}");
    assert_eq!(
        std::fs::read_to_string(fresh.join("tables.tex")).unwrap(),
        "% my edits\n"
    );
}

/// A case file, a manifest or a case's mesh that is a named pipe, a device or a directory is
/// refused by name before it is read (a named pipe would block the run until killed); a run
/// that has not ended after 60 s fails the test.
#[test]
fn pipes_devices_and_directories_are_refused_by_name_before_they_are_read() {
    let dir = std::env::temp_dir().join(format!("verify-special-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let pipe = dir.join("case.toml");
    assert!(Command::new("mkfifo")
        .arg(&pipe)
        .status()
        .unwrap()
        .success());
    let within_a_minute = |args: &[&std::ffi::OsStr]| {
        let mut command = verify();
        command.args(args);
        let output = output_within_a_minute(command);
        assert!(!output.status.success());
        String::from_utf8_lossy(&output.stderr).into_owned()
    };
    let out = dir.join("out");
    for (path, kind) in [(pipe.as_path(), "named pipe"), (dir.as_path(), "directory")] {
        let message = within_a_minute(&[
            "--case".as_ref(),
            path.as_os_str(),
            "--out".as_ref(),
            out.as_os_str(),
        ]);
        assert!(
            message.contains("case file")
                && message.contains(kind)
                && !message.contains("panicked"),
            "{message}"
        );
    }
    let manifest = dir.join("manifest.json");
    assert!(Command::new("mkfifo")
        .arg(&manifest)
        .status()
        .unwrap()
        .success());
    let message = within_a_minute(&[
        "run".as_ref(),
        "--manifest".as_ref(),
        manifest.as_os_str(),
        "--index".as_ref(),
        "0".as_ref(),
    ]);
    assert!(
        message.contains("manifest") && message.contains("named pipe"),
        "{message}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A moduli law that passes its sampled check at load but is negative in a band the damage of
/// the runs reaches (β ≈ 0.704): the failed runs name the case file and the law's key under
/// `[laws]`, the damage, the point and the time.
#[test]
fn verify_names_the_key_of_a_law_that_leaves_its_range_during_the_runs() {
    let dir = scratch("moduli-range");
    let case = changed_zones2d(
        &dir,
        "elasticity = { kind = \"damaged_hooke\", shear_modulus = 1.0, lame_lambda = 1.0 }",
        "elasticity = { kind = \"moduli\", shear_modulus = \"1 + 0.002/(beta - 0.705)\", \
         lame_lambda = \"1\" }",
    );
    let output = verify()
        .args(["--case", case.to_str().unwrap(), "--levels", "2", "--out"])
        .arg(dir.join("out"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("case `")
            && stderr.contains("changed.toml`, key `laws.elasticity.shear_modulus`")
            && stderr.contains("quadrature point")
            && stderr.contains("at t = "),
        "{stderr}"
    );
}

/// `--set NAME=VALUE` changes a constant of the case before anything runs (the case is renamed
/// so that its reports do not pass for the case's own); an unknown constant or a value that is
/// not a number is refused naming the option and the constants the case has.
#[test]
fn set_changes_a_constant_of_the_case_and_refuses_unknown_ones() {
    let dir = scratch("set");
    for (assignment, reason) in [
        (
            "x_slipp=0.5",
            "no constant `x_slipp` (its constants: x_bound, x_slip)",
        ),
        ("x_slip=half", "`half` is not a finite number"),
        ("x_slip", "write NAME=VALUE"),
    ] {
        let stderr = refused(
            &["--case", "zones2d", "--set", assignment],
            &dir.join("refused"),
        );
        assert!(
            stderr.contains(&format!("--set `{assignment}`")) && stderr.contains(reason),
            "{stderr}"
        );
    }
    let total_error = |flags: &[&str], out: &str| {
        let output = verify()
            .args([
                "--case",
                "zones2d",
                "--studies",
                "h",
                "--levels",
                "2",
                "--out",
            ])
            .arg(dir.join(out))
            .args(flags)
            .env("CI", "1")
            .output()
            .unwrap();
        // a verdict (two coarse levels: not yet certified), not an input error (status 2)
        assert_ne!(
            output.status.code(),
            Some(2),
            "{}",
            String::from_utf8_lossy(&output.stderr)
        );
        let json: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(dir.join(out).join("summary.json")).unwrap(),
        )
        .unwrap();
        (
            json["case"].as_str().unwrap().to_string(),
            std::fs::read_to_string(dir.join(out).join("errors.csv")).unwrap(),
        )
    };
    let (name, errors) = total_error(&[], "as-written");
    let (set_name, set_errors) = total_error(&["--set", "x_slip=0.5"], "set");
    assert_eq!(name, "zones2d");
    assert_eq!(set_name, "zones2d-x_slip0.5");
    assert_ne!(errors, set_errors, "the constant did not reach the runs");
}
