//! End-to-end tests of studies beyond one process: `verify plan`, `verify run`
//! (`--index`, `--shard`) and `verify merge`, and the results cache of a plain `verify`.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn verify() -> Command {
    let mut command = Command::new(env!("CARGO_BIN_EXE_verify"));
    command.env("CI", "1");
    command
}

/// A fresh scratch folder for one test.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("verify-sweep-{name}-{}", std::process::id()));
    std::fs::remove_dir_all(&dir).ok();
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn text(output: &Output) -> String {
    format!(
        "status {:?}\nstdout:\n{}\nstderr:\n{}",
        output.status.code(),
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    )
}

/// Runs `command` and returns its stdout; it must end with status 0, or with status 3 and the
/// verdict DRIFTING: the two-level studies of these tests have no fit, so they certify nothing
/// (that is not what these tests are about; a FAIL or an error still fails them).
fn run_ok(command: &mut Command) -> String {
    let output = command.output().unwrap();
    let stdout = String::from_utf8_lossy(&output.stdout).into_owned();
    let done = output.status.success()
        || (output.status.code() == Some(3) && stdout.contains("\nverdict: DRIFTING"));
    assert!(done, "{:?}\n{}", command, text(&output));
    stdout
}

/// The (cached, computed) counts of the line `cached: C runs, computed: N runs`.
fn counts(stdout: &str) -> (usize, usize) {
    let line = stdout
        .lines()
        .find(|l| l.starts_with("cached: "))
        .unwrap_or_else(|| panic!("no `cached:` line in\n{stdout}"));
    let numbers: Vec<usize> = line
        .split(|c: char| !c.is_ascii_digit())
        .filter(|s| !s.is_empty())
        .map(|s| s.parse().unwrap())
        .collect();
    (numbers[0], numbers[1])
}

/// The options of the small study of these tests: zones2d, l = 1, two levels of each study
/// (6 runs: h and diagonal share their coarsest run; the k-study has a reference run).
const STUDY: [&str; 6] = [
    "--levels",
    "2",
    "--studies",
    "h,k,diagonal",
    "--threads",
    "1",
];

/// A CSV report without its `wall_seconds` column (`rates.csv` has none).
fn csv_without_wall_time(path: &Path) -> String {
    let csv = std::fs::read_to_string(path).unwrap();
    let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    let Some(wall) = header.iter().position(|h| *h == "wall_seconds") else {
        return csv;
    };
    csv.lines()
        .map(|line| {
            let mut cells: Vec<&str> = line.split(',').collect();
            assert_eq!(cells.len(), header.len(), "{line}");
            cells.remove(wall);
            cells.join(",")
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// `summary.json` without its `wall_seconds` lines (pretty JSON: one field a line).
fn json_without_wall_time(path: &Path) -> String {
    let json = std::fs::read_to_string(path).unwrap();
    assert!(json.contains("\"wall_seconds\""), "{json}");
    json.lines()
        .filter(|line| !line.contains("\"wall_seconds\""))
        .collect::<Vec<_>>()
        .join("\n")
}

/// The report files of a folder (not the manifest, not the results folder, not the record of
/// the files written, whose digests hold those of the wall times).
fn reports(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|name| {
            name != "manifest.json" && name != "runs" && name != contact_input::written::RECORD
        })
        .collect();
    names.sort();
    names
}

#[test]
fn shards_run_in_parallel_then_merged_give_the_reports_of_a_single_process_run() {
    let dir = scratch("shards");
    let single = dir.join("single");
    let stdout = run_ok(verify().args(STUDY).arg("--out").arg(&single));
    assert_eq!(counts(&stdout), (0, 6), "{stdout}");

    let cluster = dir.join("cluster");
    let manifest = cluster.join("manifest.json");
    let planned = run_ok(
        verify()
            .arg("plan")
            .args(STUDY)
            .arg("--manifest")
            .arg(&manifest),
    );
    assert!(planned.contains("\nruns: 6\n"), "{planned}");
    // the manifest is the single-process run's own
    assert_eq!(
        std::fs::read_to_string(&manifest).unwrap(),
        std::fs::read_to_string(single.join("manifest.json")).unwrap()
    );

    // three shares, two at a time: GNU parallel when installed, else xargs -P 2
    let exe = env!("CARGO_BIN_EXE_verify");
    let manifest_arg = manifest.display().to_string();
    let parallel = Command::new("sh")
        .args(["-c", "command -v parallel"])
        .output()
        .map(|o| o.status.success())
        .unwrap_or(false);
    let script = if parallel {
        println!("running the shares with GNU parallel -j 2");
        format!("parallel -j 2 '{exe}' run --manifest '{manifest_arg}' --threads 1 --shard {{}}/3 ::: 0 1 2")
    } else {
        println!(
            "GNU parallel is not installed: running the shares with xargs -P 2 (the fallback)"
        );
        format!("printf '0\\n1\\n2\\n' | xargs -P 2 -I{{}} '{exe}' run --manifest '{manifest_arg}' --threads 1 --shard {{}}/3")
    };
    let shares = run_ok(Command::new("sh").args(["-c", &script]).env("CI", "1"));
    let computed: usize = shares
        .lines()
        .filter(|l| l.starts_with("cached: "))
        .map(|l| counts(l).1)
        .sum();
    // each run once; the reference may be computed by a second share that finds no result yet
    assert!(
        (6..=7).contains(&computed),
        "{computed} runs computed:\n{shares}"
    );

    let merged = run_ok(verify().args(["merge", "--manifest"]).arg(&manifest));
    assert!(merged.contains("verdict: DRIFTING"), "{merged}");
    let names = reports(&single);
    assert_eq!(names, reports(&cluster));
    assert!(
        names.contains(&"errors.csv".to_string()) && names.contains(&"summary.json".to_string())
    );
    for name in &names {
        let (a, b) = (single.join(name), cluster.join(name));
        if name.ends_with(".csv") {
            assert_eq!(
                csv_without_wall_time(&a),
                csv_without_wall_time(&b),
                "{name}"
            );
        } else if name.ends_with(".json") {
            assert_eq!(
                json_without_wall_time(&a),
                json_without_wall_time(&b),
                "{name}"
            );
        } else {
            // SVG plots, report.md and tables.tex hold no wall time: byte-identical
            assert_eq!(
                std::fs::read(&a).unwrap(),
                std::fs::read(&b).unwrap(),
                "{name}"
            );
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn an_interrupted_study_resumes_and_computes_only_the_missing_runs() {
    let dir = scratch("resume");
    let manifest = dir.join("manifest.json");
    run_ok(verify().arg("plan").args(STUDY).arg("--out").arg(&dir));
    // the study stopped after its two h-runs (indices 0 and 1: the manifest lists the runs of
    // the h-study, then the k-study's reference and levels, then the diagonal study's new run)
    for index in ["0", "1"] {
        let stdout = run_ok(
            verify()
                .args(["run", "--manifest"])
                .arg(&manifest)
                .args(["--index", index]),
        );
        assert_eq!(counts(&stdout), (0, 1), "{stdout}");
    }
    // merging now names the missing runs of the studies and is not a PASS (the k-study's
    // reference run is not merged itself: its levels are measured against it)
    let output = verify()
        .args(["merge", "--manifest"])
        .arg(&manifest)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert_eq!(output.status.code(), Some(1), "{}", text(&output));
    assert_eq!(stdout.matches(": missing (").count(), 3, "{stdout}");
    for id in ["l1-c16-n2-ref128", "l1-c16-n4-ref128", "l1-c8-n4"] {
        assert!(
            stdout.contains(&format!("run {id} (index ")),
            "{id}: {stdout}"
        );
    }
    assert!(
        stdout.contains("verdict: INCOMPLETE") && !stdout.contains("PASS"),
        "{stdout}"
    );
    assert!(!dir.join("summary.json").exists());

    // restarted: only the four missing runs are computed
    let stdout = run_ok(verify().args(STUDY).arg("--out").arg(&dir));
    assert_eq!(counts(&stdout), (2, 4), "{stdout}");
    assert_eq!(stdout.matches("computed run ").count(), 4, "{stdout}");
    assert!(stdout.contains("verdict: DRIFTING"), "{stdout}");
    let stdout = run_ok(verify().args(STUDY).arg("--out").arg(&dir));
    assert_eq!(counts(&stdout), (6, 0), "{stdout}");
    let stdout = run_ok(verify().args(STUDY).arg("--out").arg(&dir).arg("--fresh"));
    assert_eq!(counts(&stdout), (0, 6), "{stdout}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_changed_case_file_invalidates_exactly_the_runs_whose_digest_changed() {
    let dir = scratch("changed");
    let original = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../verification/zones2d.toml"),
    )
    .unwrap();
    let case = dir.join("case.toml");
    let out = dir.join("out");
    let study = |content: &str| {
        std::fs::write(&case, content).unwrap();
        let output = verify()
            .args([
                "--levels",
                "2",
                "--studies",
                "h,diagonal",
                "--threads",
                "1",
                "--case",
            ])
            .arg(&case)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        assert!(output.status.code() != Some(2), "{}", text(&output));
        counts(&String::from_utf8_lossy(&output.stdout))
    };
    // h: (4, 2), (8, 8); diagonal: (4, 2), (8, 4): three runs
    assert_eq!(study(&original), (0, 3));
    // a comment changes no digest
    assert_eq!(study(&format!("# note\n{original}")), (3, 0));
    // the finer h level gets other steps: that run only
    let h_line = "h = { cells = [4, 8, 16, 32], steps = [2, 8, 32, 128] }";
    assert!(original.contains(h_line));
    let finer = original.replacen(
        h_line,
        "h = { cells = [4, 8, 16, 32], steps = [2, 16, 32, 128] }",
        1,
    );
    assert_eq!(study(&finer), (2, 1));
    // another final time changes every run
    assert!(finer.contains("final_time = 1.0"));
    assert_eq!(
        study(&finer.replacen("final_time = 1.0", "final_time = 0.5", 1)),
        (0, 3)
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_corrupt_or_truncated_result_is_detected_and_recomputed_never_merged() {
    let dir = scratch("corrupt");
    let args = ["--levels", "2", "--studies", "h", "--threads", "1", "--out"];
    run_ok(verify().args(args).arg(&dir));
    let before = csv_without_wall_time(&dir.join("errors.csv"));
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir.join("runs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    files.sort();
    assert_eq!(files.len(), 2);
    // one truncated, one with a digit of its payload changed (a valid number, a wrong one)
    let bytes = std::fs::read(&files[0]).unwrap();
    std::fs::write(&files[0], &bytes[..bytes.len() - 10]).unwrap();
    let payload = String::from_utf8(std::fs::read(&files[1]).unwrap()).unwrap();
    let at = payload.find("\"h\":").unwrap() + 5;
    let mut changed = payload.into_bytes();
    changed[at] = if changed[at] == b'1' { b'2' } else { b'1' };
    std::fs::write(&files[1], &changed).unwrap();

    let output = verify()
        .args(["merge", "--manifest"])
        .arg(dir.join("manifest.json"))
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert_eq!(output.status.code(), Some(1), "{}", text(&output));
    assert!(
        stdout.contains("truncated") && stdout.contains("checksum"),
        "{stdout}"
    );
    assert_eq!(stdout.matches("invalid result").count(), 2, "{stdout}");
    assert!(stdout.contains("verdict: INCOMPLETE"), "{stdout}");

    let output = verify().args(args).arg(&dir).output().unwrap();
    let stdout = String::from_utf8_lossy(&output.stdout);
    let stderr = String::from_utf8_lossy(&output.stderr);
    // the two-level study certifies nothing (status 3), but every run has a result
    assert_eq!(output.status.code(), Some(3), "{}", text(&output));
    assert_eq!(stderr.matches("recomputing").count(), 2, "{stderr}");
    assert_eq!(counts(&stdout), (0, 2), "{stdout}");
    assert_eq!(csv_without_wall_time(&dir.join("errors.csv")), before);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_bad_manifest_index_or_shard_gets_a_clear_error() {
    let dir = scratch("bad");
    let manifest = dir.join("manifest.json");
    let fails = |args: &[&str], expected: &str| {
        let output = verify().args(args).output().unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(2), "{args:?}\n{}", text(&output));
        assert!(
            stderr.contains(expected),
            "{args:?}: `{expected}` not in\n{stderr}"
        );
    };
    let path = manifest.display().to_string();
    fails(
        &["run", "--manifest", &path, "--index", "0"],
        "manifest.json",
    );
    std::fs::write(&manifest, "{ not json").unwrap();
    fails(
        &["merge", "--manifest", &path],
        "not a manifest of `verify plan`",
    );
    // (the broken manifest is this test's own file: replaced with --overwrite)
    run_ok(verify().args([
        "plan",
        "--levels",
        "2",
        "--studies",
        "h",
        "--manifest",
        &path,
        "--overwrite",
    ]));
    fails(
        &["run", "--manifest", &path, "--index", "9"],
        "--index 9: the manifest has 2 runs",
    );
    fails(
        &[
            "run",
            "--manifest",
            &path,
            "--index",
            "18446744073709551615",
        ],
        "--index 18446744073709551615: the manifest has 2 runs (0 ..= 1)",
    );
    for shard in ["2/2", "1", "x/3", "0/0"] {
        fails(
            &["run", "--manifest", &path, "--shard", shard],
            &format!("--shard `{shard}`"),
        );
    }
    // a share count is bounded by the runs before it sizes anything
    for shard in ["0/3", "0/100000000000", "0/18446744073709551615"] {
        fails(
            &["run", "--manifest", &path, "--shard", shard],
            &format!("--shard `{shard}`: N = {} is above the 2 runs of the manifest; N must be at most 2", &shard[2..]),
        );
    }
    fails(&["run", "--manifest", &path], "--index");
    fails(
        &["run", "--manifest", &path, "--index", "0", "--shard", "0/2"],
        "cannot be used with",
    );
    // a manifest edited by hand is refused, naming the run
    let text = std::fs::read_to_string(&manifest).unwrap();
    std::fs::write(&manifest, text.replacen("\"steps\": 8", "\"steps\": 9", 1)).unwrap();
    fails(
        &["run", "--manifest", &path, "--index", "1"],
        "run l1-c8-n8 (index 1) does not match",
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// The runs of the sweep (each stored in its file, the k-levels against the stored states of
/// their reference run) give exactly the errors of the in-memory studies of `verify::study`.
#[test]
fn the_stored_runs_give_the_errors_of_the_in_memory_studies() {
    use verify::case::{parse_case_file, Case, LevelStudy, TimeStudy};
    use verify::study::{level_study, time_study, StudyKind};
    let dir = scratch("in-memory");
    run_ok(verify().args(STUDY).arg("--out").arg(&dir));
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();

    let (_, text) = verify::cli::BUILT_IN_CASES
        .iter()
        .find(|(name, _)| *name == "zones2d")
        .unwrap();
    let case = Case::<2>::new(parse_case_file(text, "zones2d").unwrap(), "zones2d").unwrap();
    let level = |cells: &[usize], steps: &[usize]| LevelStudy {
        cells: cells.to_vec(),
        refinements: Vec::new(),
        steps: steps.to_vec(),
    };
    let k = &case.file.studies["order1"].k.clone().unwrap();
    // on one thread of a pool of its own (the global pool serves the other tests)
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let in_memory = pool.install(|| {
        [
            level_study(&case, 1, StudyKind::H, &level(&[4, 8], &[2, 8])).unwrap(),
            time_study(
                &case,
                1,
                &TimeStudy {
                    cells: k.cells,
                    refinements: None,
                    steps: k.steps[..2].to_vec(),
                    reference_steps: k.reference_steps,
                },
            )
            .unwrap(),
            level_study(&case, 1, StudyKind::Diagonal, &level(&[4, 8], &[2, 4])).unwrap(),
        ]
    });
    let studies = summary["studies"].as_array().unwrap();
    assert_eq!(studies.len(), 3);
    for (study, json) in in_memory.iter().zip(studies) {
        assert_eq!(json["kind"], study.kind.name());
        assert_eq!(
            json["verdict"],
            serde_json::to_value(study.verdict).unwrap()
        );
        for (run, stored) in study.runs.iter().zip(json["runs"].as_array().unwrap()) {
            assert_eq!(stored["steps"], run.steps);
            for (name, value) in verify::error_norms::ErrorComponents::NAMES
                .iter()
                .zip(run.errors.values())
            {
                let stored = stored["errors"][name].as_f64();
                assert_eq!(stored, value.is_finite().then_some(value), "{name}");
            }
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// A stand-in for Slurm's `sbatch` (Slurm is not installed here): it logs its arguments, runs
/// the job at once — each task of an `--array=A-B` in turn, with `SLURM_ARRAY_TASK_ID` set —
/// and prints a job id as `--parsable` does (1000 + the number of submissions so far).
const FAKE_SBATCH: &str = r#"#!/bin/bash
array=""
script=""
for arg in "$@"; do
  case "$arg" in
    --array=*) array=${arg#--array=} ;;
    --*) ;;
    *) script=$arg ;;
  esac
done
echo "sbatch $*" >> "$SBATCH_LOG"
if [ -n "$array" ]; then
  for ((i = ${array%-*}; i <= ${array#*-}; i++)); do
    SLURM_ARRAY_TASK_ID=$i bash "$script" >> "$SBATCH_LOG" 2>&1 || exit 1
  done
else
  bash "$script" >> "$SBATCH_LOG" 2>&1
  echo "job exit $?" >> "$SBATCH_LOG"
fi
echo "$((1000 + $(grep -c '^sbatch ' "$SBATCH_LOG")));cluster"
"#;

#[test]
fn the_slurm_scripts_run_every_run_as_an_array_task_then_merge() {
    let dir = scratch("slurm");
    let bin = dir.join("bin");
    std::fs::create_dir_all(&bin).unwrap();
    let sbatch = bin.join("sbatch");
    std::fs::write(&sbatch, FAKE_SBATCH).unwrap();
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&sbatch, std::fs::Permissions::from_mode(0o755)).unwrap();
    }
    let log = dir.join("sbatch.log");
    std::fs::write(&log, "").unwrap();
    let submit = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/cluster/submit.sh");
    let study = dir.join("study");
    let path = format!(
        "{}:{}",
        bin.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let stdout = run_ok(
        Command::new("bash")
            .arg(&submit)
            .arg(&study)
            .args(STUDY)
            .env("PATH", path)
            .env("VERIFY", env!("CARGO_BIN_EXE_verify"))
            .env("SBATCH_LOG", &log)
            .env("CI", "1")
            .env("SLURM_CPUS_PER_TASK", "1"),
    );
    let log = std::fs::read_to_string(&log).unwrap();
    println!("{stdout}\n{log}");
    assert!(stdout.contains("6 runs in job array"), "{stdout}");
    // the array covers the runs; the merge job depends on the array's id
    let submissions: Vec<&str> = log.lines().filter(|l| l.starts_with("sbatch ")).collect();
    assert_eq!(submissions.len(), 2, "{log}");
    assert!(submissions[0].contains("--array=0-5"), "{log}");
    let array_id = 1001; // the fake's id of the first submission
    assert!(
        submissions[1].contains(&format!("--dependency=afterok:{array_id}")),
        "{log}"
    );
    // six tasks, each a run of its own; the task of the k-study's reference finds it stored
    // when a level before it needed it (one task per run either way)
    let tasks = log.matches("cached: ").count();
    assert_eq!(tasks, 6, "{log}");
    // the merge job ends with the status of `verify merge`: 3, as the two-level study is not
    // certified
    assert!(
        log.contains("verdict: DRIFTING") && log.contains("job exit 3"),
        "{log}"
    );
    assert!(study.join("summary.json").exists() && study.join("errors.csv").exists());
    std::fs::remove_dir_all(&dir).ok();
}
