//! Golden images: small offscreen renders compared with stored PNGs.
//!
//! On failure the test writes `<name>-actual.png` and `<name>-diff.png` beside the golden file.
//! `HOOKE_BLESS=1 cargo test -p hooke-gpu --test golden` stores the current renders as golden.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use hooke::{OffscreenRun, Simulation, SolverChoice};
use hooke_core::scene::{MeshSection, SceneFile};
use hooke_gpu::render::Image;
use hooke_gpu::{GpuContext, GpuMethod, test_context};

/// A channel may be off by this much (rasterisation and float differences between drivers).
const CHANNEL_THRESHOLD: u8 = 24;
/// Share of pixels allowed beyond the threshold.
const DIFFERING_SHARE: f64 = 0.01;
/// How far a pixel may land from its golden place: edges and one-pixel spring lines move by a
/// pixel between rasterisers (lavapipe builds differ in how they round line ends).
const SHIFT: u32 = 1;

fn golden_path(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/golden")
        .join(format!("{name}.png"))
}

/// The Fig. 2 set-up on a 16 x 16 cloth, 200 steps, drawn at 160 x 120.
fn render(context: &Arc<GpuContext>, wireframe: bool, strain: bool) -> Image {
    let mut file = SceneFile::benchmark(MeshSection::unit_grid(16, 16), 256);
    file.mesh.center = [0.0, 1.0, 0.0];
    file.material.stiffness = 20.0;
    file.material.damping = 0.002;
    file.simulation.dt = hooke_core::scene::TimeStep::Auto;
    let scene = file.build(Path::new("golden"), false).expect("scene");
    let simulation = Simulation::from_scene(
        &scene,
        SolverChoice::Gpu(GpuMethod::Gather),
        Some(Arc::clone(context)),
    )
    .expect("solver");
    let mut run = OffscreenRun::new(simulation, [160, 120]).expect("renderer");
    run.options.wireframe = wireframe;
    run.options.color_by_strain = strain;
    run.frame(200).expect("frame")
}

/// Compares `actual` with the golden image `name`, blessing it when HOOKE_BLESS=1.
fn check_golden(name: &str, actual: &Image) -> Result<(), String> {
    let path = golden_path(name);
    if std::env::var("HOOKE_BLESS").is_ok_and(|v| v == "1") {
        actual.save_png(&path).map_err(|e| e.to_string())?;
        return Ok(());
    }
    let expected = Image::load_png(&path).map_err(|e| format!("{e} (bless with HOOKE_BLESS=1)"))?;
    let verdict = match actual.difference(&expected, CHANNEL_THRESHOLD, SHIFT) {
        None => Err(format!(
            "size {:?} differs from golden {:?}",
            actual.size, expected.size
        )),
        Some(d) if d.differing_share > DIFFERING_SHARE => {
            let _ = d
                .diff
                .save_png(&path.with_file_name(format!("{name}-diff.png")));
            Err(format!(
                "{:.2}% of pixels differ by more than {CHANNEL_THRESHOLD} (max {})",
                100.0 * d.differing_share,
                d.max
            ))
        }
        Some(_) => Ok(()),
    };
    if verdict.is_err() {
        let _ = actual.save_png(&path.with_file_name(format!("{name}-actual.png")));
    }
    verdict
}

#[test]
fn cloth_pinned_render_matches_golden() {
    let Some(context) = test_context() else {
        return;
    };
    let image = render(&context, false, false);
    check_golden("cloth-pinned", &image).unwrap_or_else(|e| panic!("cloth-pinned: {e}"));
}

#[test]
fn strain_wireframe_render_matches_golden() {
    let Some(context) = test_context() else {
        return;
    };
    let image = render(&context, true, true);
    check_golden("cloth-pinned-strain-wire", &image)
        .unwrap_or_else(|e| panic!("strain wireframe: {e}"));
}

#[test]
fn comparison_catches_a_change() {
    let Some(context) = test_context() else {
        return;
    };
    if std::env::var("HOOKE_BLESS").is_ok_and(|v| v == "1") {
        return;
    }
    // The wireframe render is a different picture: it must not pass as the plain golden one.
    let changed = render(&context, true, false);
    let expected = Image::load_png(&golden_path("cloth-pinned")).expect("golden image");
    let difference = changed
        .difference(&expected, CHANNEL_THRESHOLD, SHIFT)
        .expect("same size");
    assert!(
        difference.differing_share > DIFFERING_SHARE,
        "{:.3}%",
        100.0 * difference.differing_share
    );
}

#[test]
fn renders_are_identical_run_to_run() {
    let Some(context) = test_context() else {
        return;
    };
    assert_eq!(
        render(&context, false, false),
        render(&context, false, false)
    );
}
