//! `hooke render`: simulate on the GPU and draw offscreen, to PNG frames, one PNG, or an MP4.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use anyhow::{Context, bail};
use clap::Args;
use hooke::{OffscreenRun, Simulation, SolverChoice};
use hooke_gpu::GpuMethod;
use hooke_gpu::render::Image;
use indicatif::{ProgressBar, ProgressStyle};

use crate::scene_loading::load_scene;
use crate::solvers::{AccumulationArg, MethodArg, open_gpu};

#[derive(Debug, Args)]
pub struct RenderArgs {
    /// Scene file (TOML).
    pub scene: PathBuf,
    /// A directory (one PNG per frame), a .png file (the last frame) or an .mp4 file (needs ffmpeg).
    #[arg(long)]
    pub out: PathBuf,
    /// Frames to render (default: the scene's steps / frame_every, plus the first).
    #[arg(long)]
    pub frames: Option<u32>,
    /// Steps between frames (default: the scene's simulation.frame_every).
    #[arg(long)]
    pub steps_per_frame: Option<u32>,
    /// Image size, WIDTHxHEIGHT.
    #[arg(long, default_value = "960x540", value_parser = parse_size)]
    pub size: [u32; 2],
    /// Frames per second of an MP4.
    #[arg(long, default_value_t = 30)]
    pub fps: u32,
    #[arg(long, value_enum, default_value_t = MethodArg::Scatter)]
    pub method: MethodArg,
    #[arg(long, value_enum, default_value_t = AccumulationArg::Incidence)]
    pub accumulation: AccumulationArg,
    /// Colour the cloth by strain instead of a checker pattern.
    #[arg(long)]
    pub strain: bool,
    /// Draw the springs.
    #[arg(long)]
    pub wireframe: bool,
    /// Run even if dt exceeds the stability bound.
    #[arg(long)]
    pub allow_unstable: bool,
}

pub fn parse_size(text: &str) -> Result<[u32; 2], String> {
    let (w, h) = text
        .split_once('x')
        .ok_or_else(|| format!("expected WIDTHxHEIGHT, found {text:?}"))?;
    let parse = |s: &str| s.parse::<u32>().ok().filter(|v| (16..=8192).contains(v));
    match (parse(w), parse(h)) {
        (Some(w), Some(h)) => Ok([w, h]),
        _ => Err(format!(
            "each side must be 16..=8192 pixels, found {text:?}"
        )),
    }
}

enum Output {
    Directory(PathBuf),
    LastFrame(PathBuf),
    Video(std::process::Child, PathBuf),
}

/// Steps between frames and the number of frames: the flags, or the scene's `frame_every` and
/// `steps` (one frame at the start, then one every `frame_every` steps). Values the render loop
/// cannot count (more than `u32::MAX` of either) are refused with the field named.
fn frame_plan(
    steps: u64,
    frame_every: u64,
    steps_per_frame: Option<u32>,
    frames: Option<u32>,
) -> anyhow::Result<(u32, u32)> {
    let steps_per_frame = match steps_per_frame {
        Some(n) => n.max(1),
        None => u32::try_from(frame_every.max(1)).map_err(|_| {
            anyhow::anyhow!(
                "simulation.frame_every = {frame_every} is more steps between frames than hooke render takes ({}); give --steps-per-frame",
                u32::MAX
            )
        })?,
    };
    let frames = match frames {
        Some(n) => n.max(1),
        None => (steps / u64::from(steps_per_frame))
            .checked_add(1)
            .and_then(|n| u32::try_from(n).ok())
            .ok_or_else(|| {
                anyhow::anyhow!(
                    "simulation.steps = {steps} makes more frames than hooke render writes ({}); give --frames",
                    u32::MAX
                )
            })?,
    };
    Ok((steps_per_frame, frames))
}

pub fn run(args: &RenderArgs) -> anyhow::Result<()> {
    let scene = load_scene(&args.scene, args.allow_unstable)?;
    let (steps_per_frame, frames) = frame_plan(
        scene.steps,
        scene.frame_every,
        args.steps_per_frame,
        args.frames,
    )?;
    let method = match args.method {
        MethodArg::Gather => GpuMethod::Gather,
        MethodArg::Scatter => GpuMethod::Scatter(args.accumulation.into()),
    };
    let context = open_gpu()?;
    let simulation = Simulation::from_scene(&scene, SolverChoice::Gpu(method), Some(context))
        .context("setting up the GPU solver")?;
    let mut run = OffscreenRun::new(simulation, args.size).context("setting up the renderer")?;
    run.options.color_by_strain = args.strain;
    run.options.wireframe = args.wireframe;
    let mut output = open_output(&args.out, args.size, args.fps)?;
    eprintln!(
        "{}: {frames} frames of {}x{}, {steps_per_frame} steps apart, on {}",
        scene.name,
        args.size[0],
        args.size[1],
        run.simulation.describe()
    );
    let progress = ProgressBar::new(u64::from(frames));
    progress.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} frames  eta {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    for frame in 0..frames {
        let steps = if frame == 0 { 0 } else { steps_per_frame };
        let image = run
            .frame(steps)
            .with_context(|| format!("frame {frame} (step {})", run.steps_taken()))?;
        write_frame(&mut output, frame, &image)?;
        progress.inc(1);
    }
    progress.finish_and_clear();
    let written = finish_output(output)?;
    println!("{written}");
    Ok(())
}

fn open_output(out: &Path, size: [u32; 2], fps: u32) -> anyhow::Result<Output> {
    let extension = out
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match extension.as_deref() {
        Some("png") => Ok(Output::LastFrame(out.to_path_buf())),
        Some("mp4") => {
            let ffmpeg = Command::new("ffmpeg")
                .args([
                    "-hide_banner",
                    "-loglevel",
                    "error",
                    "-y",
                    "-f",
                    "rawvideo",
                    "-pix_fmt",
                    "rgba",
                ])
                .args([
                    "-s",
                    &format!("{}x{}", size[0], size[1]),
                    "-r",
                    &fps.to_string(),
                    "-i",
                    "-",
                ])
                .args([
                    "-c:v",
                    "libx264",
                    "-pix_fmt",
                    "yuv420p",
                    "-vf",
                    "pad=ceil(iw/2)*2:ceil(ih/2)*2",
                ])
                .arg(out)
                .stdin(Stdio::piped())
                .spawn();
            match ffmpeg {
                Ok(child) => Ok(Output::Video(child, out.to_path_buf())),
                Err(error) if error.kind() == std::io::ErrorKind::NotFound => bail!(
                    "writing {} needs ffmpeg, which is not on PATH (on Debian: apt-get install ffmpeg); \
                     or give --out a directory for PNG frames",
                    out.display()
                ),
                Err(error) => Err(error).context("starting ffmpeg"),
            }
        }
        _ => {
            std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
            Ok(Output::Directory(out.to_path_buf()))
        }
    }
}

fn write_frame(output: &mut Output, frame: u32, image: &Image) -> anyhow::Result<()> {
    match output {
        Output::Directory(directory) => {
            image.save_png(&directory.join(format!("frame-{frame:05}.png")))?;
        }
        Output::LastFrame(path) => image.save_png(path)?,
        Output::Video(child, path) => {
            let stdin = child.stdin.as_mut().context("ffmpeg's input closed")?;
            stdin
                .write_all(&image.rgba)
                .with_context(|| format!("ffmpeg stopped while writing {}", path.display()))?;
        }
    }
    Ok(())
}

fn finish_output(output: Output) -> anyhow::Result<String> {
    Ok(match output {
        Output::Directory(directory) => format!("frames written to {}", directory.display()),
        Output::LastFrame(path) => format!("last frame written to {}", path.display()),
        Output::Video(mut child, path) => {
            drop(child.stdin.take());
            let status = child.wait().context("waiting for ffmpeg")?;
            if !status.success() {
                bail!("ffmpeg failed ({status}) writing {}", path.display());
            }
            format!("video written to {}", path.display())
        }
    })
}

#[cfg(test)]
mod tests {
    use super::frame_plan;

    #[test]
    fn frame_plan_counts_frames_and_refuses_what_it_cannot_count() {
        assert_eq!(frame_plan(1000, 100, None, None).expect("plan"), (100, 11));
        assert_eq!(
            frame_plan(1000, 100, Some(10), Some(3)).expect("plan"),
            (10, 3)
        );
        assert_eq!(frame_plan(0, 0, None, None).expect("plan"), (1, 1));
        let error = frame_plan(10, u64::MAX, None, None).expect_err("too far apart");
        assert!(
            error.to_string().contains("simulation.frame_every"),
            "{error}"
        );
        let error = frame_plan(u64::MAX, 1, None, None).expect_err("too many frames");
        assert!(error.to_string().contains("simulation.steps"), "{error}");
    }
}
