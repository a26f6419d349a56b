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
    // Dynamic balls pushed by the cloth; and kinematic balls on straight and keyframed paths.
    for name in ["wind-and-balls.toml", "ball-through-curtain.toml"] {
        let scene = shipped_scene_path(name);
        for method in ["gather", "scatter"] {
            let out = |label: &str| dir.path().join(format!("{name}-{method}-{label}"));
            let (whole, first, second) = (out("whole"), out("first"), out("second"));
            run(&scene, "200", &whole, &["--method", method]);
            run(&scene, "100", &first, &["--method", method]);
            let saved = first.join("final-state.ply");
            run(
                &scene,
                "100",
                &second,
                &["--method", method, "--resume", path_str(&saved)],
            );
            for file in ["final-state.ply", "final-state.toml"] {
                let expected = std::fs::read(whole.join(file)).expect("whole run's state");
                let actual = std::fs::read(second.join(file)).expect("resumed run's state");
                assert!(
                    expected == actual,
                    "{name} {method}: {file} of 100 + 100 steps differs from 200 steps"
                );
            }
            let sidecar = std::fs::read_to_string(second.join("final-state.toml")).expect("toml");
            assert!(sidecar.contains("steps_taken = 200"), "{sidecar}");
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
