//! The scenes shipped in `scenes/` build, and the benchmark ones equal `hooke bench`'s workload.

use std::path::{Path, PathBuf};

use hooke_core::scene::{MeshSection, SceneFile};

fn scenes_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes")
}

#[test]
fn benchmark_scene_files_equal_the_bench_workload() {
    let expected = [
        (
            "bench-grid-128.toml",
            MeshSection::unit_grid(128, 128),
            128 * 128,
        ),
        (
            "bench-grid-256.toml",
            MeshSection::unit_grid(256, 256),
            256 * 256,
        ),
        (
            "bench-grid-512.toml",
            MeshSection::unit_grid(512, 512),
            512 * 512,
        ),
        (
            "bench-grid-1024.toml",
            MeshSection::unit_grid(1024, 1024),
            1024 * 1024,
        ),
        (
            "bench-irregular.toml",
            MeshSection::unit_irregular(65_536, 1),
            65_536,
        ),
    ];
    for (file, mesh, vertices) in expected {
        let loaded = SceneFile::load(&scenes_dir().join(file)).expect("parses");
        assert_eq!(loaded, SceneFile::benchmark(mesh, vertices), "{file}");
    }
}

#[test]
fn every_shipped_scene_builds() {
    let mut count = 0;
    for entry in std::fs::read_dir(scenes_dir()).expect("scenes/ exists") {
        let path = entry.expect("entry").path();
        if path.extension().is_none_or(|e| e != "toml") {
            continue;
        }
        let name = path
            .file_name()
            .and_then(|n| n.to_str())
            .unwrap_or_default()
            .to_owned();
        if name.starts_with("bench-grid-") && name != "bench-grid-128.toml" {
            continue; // large; their definitions are checked above
        }
        // The benchmark workload is fixed; on irregular meshes its dt exceeds the bound.
        let allow_unstable = name.starts_with("bench-");
        let scene = SceneFile::load(&path)
            .and_then(|s| s.build(&path, allow_unstable))
            .unwrap_or_else(|e| panic!("{e}"));
        assert!(scene.model.vertex_count() > 0, "{name}");
        count += 1;
    }
    assert!(count >= 3);
}
