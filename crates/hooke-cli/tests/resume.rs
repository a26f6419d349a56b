//! `hooke run --resume`: a run continued from its saved state ends exactly where the
//! uninterrupted run ends; a state that does not fit the scene is refused with the reason.

use std::path::Path;
use std::process::Command;

use hooke_testkit::shipped_scene_path;

fn hooke(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_hooke"))
        .args(args)
        .output()
        .expect("hooke runs")
}

fn path_str(path: &Path) -> &str {
    path.to_str().expect("utf-8 path")
}

/// Runs `hooke run` and requires success.
fn run(scene: &Path, steps: &str, output: &Path, extra: &[&str]) {
    let mut args = vec![
        "run",
        path_str(scene),
        "--steps",
        steps,
        "--no-frames",
        "--output",
        path_str(output),
    ];
    args.extend_from_slice(extra);
    let result = hooke(&args);
    assert!(
        result.status.success(),
        "{}",
        String::from_utf8_lossy(&result.stderr)
    );
}

#[test]
fn a_resumed_run_ends_bit_identical_to_the_uninterrupted_one() {
    let dir = tempfile::tempdir().expect("tempdir");
    // Dynamic balls pushed by the cloth; kinematic balls on straight and keyframed paths; a
    // sheet stopped while it tears.
    for (name, before, after) in [
        ("wind-and-balls.toml", 100, 100),
        ("ball-through-curtain.toml", 100, 100),
        ("tearing.toml", 1430, 570),
    ] {
        let scene = shipped_scene_path(name);
        let total = (before + after).to_string();
        let (before, after) = (before.to_string(), after.to_string());
        for method in ["gather", "scatter"] {
            let out = |label: &str| dir.path().join(format!("{name}-{method}-{label}"));
            let (whole, first, second) = (out("whole"), out("first"), out("second"));
            run(&scene, &total, &whole, &["--method", method]);
            run(&scene, &before, &first, &["--method", method]);
            let saved = first.join("final-state.ply");
            run(
                &scene,
                &after,
                &second,
                &["--method", method, "--resume", path_str(&saved)],
            );
            for file in ["final-state.ply", "final-state.toml"] {
                let expected = std::fs::read(whole.join(file)).expect("whole run's state");
                let actual = std::fs::read(second.join(file)).expect("resumed run's state");
                assert!(
                    expected == actual,
                    "{name} {method}: {file} of {before} + {after} steps differs from {total} steps"
                );
            }
            let sidecar = std::fs::read_to_string(second.join("final-state.toml")).expect("toml");
            assert!(
                sidecar.contains(&format!("steps_taken = {total}")),
                "{sidecar}"
            );
            if name == "tearing.toml" {
                // Stopped mid-tear: some springs broken then, more by the end, all counted.
                let count = |run: &Path| {
                    let text = std::fs::read_to_string(run.join("summary.json")).expect("summary");
                    let summary: serde_json::Value = serde_json::from_str(&text).expect("json");
                    summary["broken_springs"].as_u64().expect("broken_springs")
                };
                let (then, end) = (count(&first), count(&second));
                assert!(
                    0 < then && then < end && end == count(&whole),
                    "{then} then, {end} at the end"
                );
                let saved = std::fs::read_to_string(first.join("final-state.toml")).expect("toml");
                assert!(saved.contains("broken_springs = ["), "{saved}");
            }
        }
    }
}

#[test]
fn a_state_of_another_scene_or_time_step_is_refused_with_the_reason() {
    let dir = tempfile::tempdir().expect("tempdir");
    let balls = shipped_scene_path("wind-and-balls.toml");
    let saved = dir.path().join("balls");
    run(&balls, "10", &saved, &[]);
    let state = saved.join("final-state.ply");
    // Another mesh.
    let other = hooke(&[
        "run",
        path_str(&shipped_scene_path("cloth-pinned.toml")),
        "--steps",
        "10",
        "--no-frames",
        "--output",
        path_str(&dir.path().join("other")),
        "--resume",
        path_str(&state),
    ]);
    let stderr = String::from_utf8_lossy(&other.stderr);
    assert!(!other.status.success());
    assert!(
        stderr.contains("final-state.ply") && stderr.contains("vertices"),
        "{stderr}"
    );
    // The same scene at another dt.
    let text = std::fs::read_to_string(&balls).expect("scene");
    let faster = dir.path().join("faster.toml");
    std::fs::write(&faster, text.replace("dt = \"auto\"", "dt = 1e-5")).expect("w");
    let result = hooke(&[
        "run",
        path_str(&faster),
        "--steps",
        "10",
        "--no-frames",
        "--output",
        path_str(&dir.path().join("faster")),
        "--resume",
        path_str(&state),
    ]);
    let stderr = String::from_utf8_lossy(&result.stderr);
    assert!(!result.status.success());
    assert!(
        stderr.contains("final-state.toml") && stderr.contains("dt"),
        "{stderr}"
    );
    // No sidecar: the error names the missing file.
    std::fs::remove_file(saved.join("final-state.toml")).expect("remove");
    let result = hooke(&[
        "run",
        path_str(&balls),
        "--steps",
        "10",
        "--no-frames",
        "--output",
        path_str(&dir.path().join("bare")),
        "--resume",
        path_str(&state),
    ]);
    let stderr = String::from_utf8_lossy(&result.stderr);
    assert!(!result.status.success());
    assert!(stderr.contains("final-state.toml"), "{stderr}");
}
