//! Every seed of the fuzzers and every input that ever crashed a reader (`fuzz/regressions/`),
//! run through the same harness the fuzzers use: none may panic. The shipped scenes seed the
//! scene target too.

use std::path::{Path, PathBuf};

fn fuzz_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz")
}

fn files_in(dir: &Path) -> Vec<PathBuf> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut files: Vec<PathBuf> = entries
        .map(|e| e.expect("folder entry").path())
        .filter(|p| p.is_file() && !p.ends_with(".gitkeep"))
        .collect();
    files.sort();
    files
}

#[test]
fn seeds_and_regressions_pass_through_every_reader_without_a_panic() {
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    for (name, target) in hooke_fuzz::TARGETS {
        let seeds = files_in(&fuzz_dir().join("seeds").join(name));
        assert!(!seeds.is_empty(), "{name}: no seeds in fuzz/seeds/{name}");
        let mut inputs = seeds;
        inputs.extend(files_in(&fuzz_dir().join("regressions").join(name)));
        if name == "scene" {
            inputs.extend(
                files_in(&scenes)
                    .into_iter()
                    .filter(|p| p.extension().is_some_and(|e| e == "toml")),
            );
        }
        for input in &inputs {
            let data = std::fs::read(input).expect("read input");
            let result = std::panic::catch_unwind(|| target(&data));
            assert!(result.is_ok(), "{name}: {} panics", input.display());
        }
        eprintln!("{name}: {} inputs replayed", inputs.len());
    }
}
