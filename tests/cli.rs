//! End-to-end tests of the `verify` command line: reports are written, bad input gets a clear
//! error and a non-zero exit status.

use std::process::Command;

fn verify() -> Command {
    Command::new(env!("CARGO_BIN_EXE_verify"))
}

#[test]
fn verify_writes_csv_json_and_svg_reports() {
    let out = std::env::temp_dir().join(format!("verify-cli-{}", std::process::id()));
    let status = verify()
        .args([
            "--order",
            "1",
            "--levels",
            "3",
            "--studies",
            "h,diagonal",
            "--out",
        ])
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
    assert_eq!(csv.lines().count(), 1 + 6, "header + 2 studies × 3 runs");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(json["case"], "zones2d");
    assert_eq!(json["studies"].as_array().unwrap().len(), 2);
    let svg = std::fs::read_to_string(out.join("h-l1.svg")).unwrap();
    assert!(svg.contains("<svg") && svg.contains("damage gradient"));
    // no temporary file left behind
    for entry in std::fs::read_dir(&out).unwrap() {
        let name = entry.unwrap().file_name().into_string().unwrap();
        assert!(!name.contains("tmp"), "leftover temporary file {name}");
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
