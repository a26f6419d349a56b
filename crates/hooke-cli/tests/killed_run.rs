//! A run killed with SIGKILL while it writes frames leaves no torn file: every file under an
//! output name is whole, and what was being written is a hidden `.partial` file.

use std::collections::HashSet;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant, SystemTime};

use hooke_core::mesh::load_mesh;
use hooke_testkit::shipped_scene_path;

/// 128 x 128 vertices: a frame is ~0.6 MB, written every step.
const VERTICES: usize = 128 * 128;

fn frames_in(dir: &Path) -> Vec<std::path::PathBuf> {
    let mut frames: Vec<_> = std::fs::read_dir(dir)
        .map(|entries| entries.map(|e| e.expect("entry").path()).collect())
        .unwrap_or_default();
    frames.retain(|p| {
        p.file_name()
            .and_then(|n| n.to_str())
            .is_some_and(|n| n.starts_with("frame-") && n.ends_with(".ply"))
    });
    frames
}

/// The hidden `.NAME.XXXXXX.partial` files in `dir`: writes that were cut off.
fn partials_in(dir: &Path) -> HashSet<String> {
    std::fs::read_dir(dir)
        .map(|entries| {
            entries
                .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
                .filter(|name| name.starts_with('.') && name.ends_with(".partial"))
                .collect()
        })
        .unwrap_or_default()
}

#[test]
fn a_run_killed_while_writing_frames_leaves_no_torn_file() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("out");
    let scene = shipped_scene_path("bench-grid-128.toml");
    const KILLS: usize = 4;
    for kill in 0..KILLS {
        let spawned = SystemTime::now();
        let mut child = Command::new(env!("CARGO_BIN_EXE_hooke"))
            .args(["run", scene.to_str().expect("utf-8"), "--frame-every", "1"])
            .args(["--steps", "1000000", "--output"])
            .arg(&out)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("hooke starts");
        // Once this run has written `kill + 1` frames (so that each kill cuts a different
        // frame's write), kill it the moment a new write is seen under way (its temporary file
        // exists).
        let before = partials_in(&out);
        let started = Instant::now();
        let written = |since: SystemTime| {
            frames_in(&out)
                .iter()
                .filter(|f| {
                    std::fs::metadata(f)
                        .and_then(|m| m.modified())
                        .is_ok_and(|t| t >= since)
                })
                .count()
        };
        while (written(spawned) <= kill || partials_in(&out).is_subset(&before))
            && started.elapsed() < Duration::from_secs(60)
        {
            std::thread::sleep(Duration::from_micros(200));
        }
        child.kill().expect("SIGKILL");
        child.wait().expect("reaped");
    }
    let partials = partials_in(&out).len();
    let frames = frames_in(&out);
    eprintln!(
        "{KILLS} kills, {partials} inside a write (a .partial left), {} frames under real names",
        frames.len()
    );
    assert!(
        partials > 0,
        "no kill landed inside a write: the test proves nothing"
    );
    assert!(
        frames.len() >= KILLS,
        "each run wrote frames before its kill"
    );
    for frame in &frames {
        let (mesh, _) =
            load_mesh(frame).unwrap_or_else(|e| panic!("{} is torn: {e}", frame.display()));
        assert_eq!(mesh.vertex_count(), VERTICES, "{}", frame.display());
    }
}

/// A run killed while it streams frames into one file (`.usda`, `.pc2`) leaves the file a
/// previous run completed, byte for byte, or none: the frames so far are in the `.partial`.
#[test]
fn a_run_killed_while_streaming_leaves_the_previous_file_or_none() {
    let scene = shipped_scene_path("bench-grid-128.toml");
    for format in ["usda", "pc2"] {
        let dir = tempfile::tempdir().expect("tempdir");
        let file = dir.path().join(format!("cloth.{format}"));
        let run = |steps: &str, frame_every: &str| {
            let mut command = Command::new(env!("CARGO_BIN_EXE_hooke"));
            command
                .args(["run", scene.to_str().expect("utf-8"), "--steps", steps])
                .args(["--frame-every", frame_every, "--output"])
                .arg(&file)
                .stdout(Stdio::null())
                .stderr(Stdio::null());
            command
        };
        // Killed once several frames are in the temporary file.
        let kill_midway = || {
            // The previous kill's temporary would look like this run's progress.
            for name in partials_in(dir.path()) {
                std::fs::remove_file(dir.path().join(name)).expect("old partial removed");
            }
            let mut child = run("1000000", "1").spawn().expect("hooke starts");
            let started = Instant::now();
            let streamed = || {
                partials_in(dir.path())
                    .iter()
                    .map(|name| std::fs::metadata(dir.path().join(name)).map_or(0, |m| m.len()))
                    .max()
                    .unwrap_or(0)
            };
            // Three frames of 16384 points: at least 12 bytes each.
            while streamed() < 3 * 12 * VERTICES as u64
                && started.elapsed() < Duration::from_secs(60)
            {
                std::thread::sleep(Duration::from_millis(2));
            }
            child.kill().expect("SIGKILL");
            child.wait().expect("reaped");
            let size = streamed();
            eprintln!("{format}: killed with {size} bytes streamed");
            assert!(
                size >= 3 * 12 * VERTICES as u64,
                "{format}: the kill landed mid-stream"
            );
        };
        kill_midway();
        assert!(
            !file.exists(),
            "{format}: a killed first run leaves no file"
        );
        let status = run("20", "10").status().expect("hooke runs");
        assert!(status.success(), "{format}: a complete run");
        let complete = std::fs::read(&file).expect("the completed file");
        kill_midway();
        assert_eq!(
            std::fs::read(&file).expect("still there"),
            complete,
            "{format}: the killed run left the previous file as it was"
        );
        assert!(dir.path().join("cloth.final-state.ply").exists());
        assert!(dir.path().join("cloth.summary.json").exists());
    }
}
