//! Fingerprint of the source code a verification result depends on: the sources of the solver
//! (`contact-damage`), the input layer (`contact-input`) and the harness (`verify`), and the
//! locked dependency versions (`Cargo.lock`). It is part of the digest of every run
//! (`sweep::plan::CODE_VERSION`), so that results cached by an earlier build of different code
//! are recomputed rather than reused.

use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};

fn files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        if path.is_dir() {
            files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

fn main() {
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("set by cargo"));
    let roots = [
        manifest.join("src"),
        manifest.join("../contact-damage/src"),
        manifest.join("../input/src"),
    ];
    let lock = manifest.join("../../Cargo.lock");
    let mut sources = Vec::new();
    for root in &roots {
        println!("cargo:rerun-if-changed={}", root.display());
        files(root, &mut sources);
    }
    println!("cargo:rerun-if-changed={}", lock.display());
    sources.sort();
    sources.push(lock);
    // SHA-256 of every file's name and length-prefixed content: the same sources give the
    // same fingerprint on every machine and with every toolchain
    let mut hasher = Sha256::new();
    for path in &sources {
        if let Ok(text) = std::fs::read(path) {
            let name = path.strip_prefix(&manifest).unwrap_or(path);
            let name = name.to_string_lossy();
            hasher.update((name.len() as u64).to_le_bytes());
            hasher.update(name.as_bytes());
            hasher.update((text.len() as u64).to_le_bytes());
            hasher.update(&text);
        }
    }
    let digest = hasher.finalize();
    let hex: String = digest[..8].iter().map(|b| format!("{b:02x}")).collect();
    println!("cargo:rustc-env=VERIFY_SOURCE_FINGERPRINT={hex}");
}
