//! USD in its text form (`.usda`), streamed: the stage's metadata and the cloth's topology go
//! out with the first frame, each frame's `points` sample as it comes, and what is small (the
//! extents, the colliders' places) at the end, when the file is renamed into place.
//!
//! Time codes are frame numbers (step / frame_every), and `timeCodesPerSecond` and
//! `framesPerSecond` make one frame last frame_every × dt, so the animation plays in real time.

use std::fmt::Write as _;
use std::io::{Seek, SeekFrom, Write};
use std::path::Path;

use glam::{DQuat, DVec3, Vec3};

use crate::atomic_file::AtomicFile;
use crate::collide::{Collider, Shape};
use crate::mesh::TextureCoordinates;

/// How steps map to time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameTiming {
    /// Seconds per step.
    pub dt: f64,
    /// Steps per written frame.
    pub frame_every: u64,
}

impl FrameTiming {
    fn time_code(&self, step: u64) -> f64 {
        step as f64 / self.frame_every.max(1) as f64
    }

    fn frames_per_second(&self) -> f64 {
        1.0 / (self.dt * self.frame_every.max(1) as f64)
    }
}

/// Side of the square drawn for a plane collider, m (a plane is infinite; USD's `Plane` is not).
const PLANE_SIZE: f64 = 20.0;

#[derive(Debug)]
pub(super) struct UsdaStream {
    file: AtomicFile,
    timing: FrameTiming,
    points: usize,
    /// Where the header's time range line starts.
    time_range_at: u64,
    /// Per frame: the time code, the cloth's bounds, the colliders.
    frames: Vec<(f64, [Vec3; 2], Vec<Collider>)>,
}

impl UsdaStream {
    pub(super) fn create(
        path: &Path,
        name: &str,
        timing: FrameTiming,
        points: usize,
        triangles: &[[u32; 3]],
        uvs: Option<&TextureCoordinates>,
    ) -> std::io::Result<Self> {
        let mut file = AtomicFile::create(path)?;
        let fps = timing.frames_per_second();
        // Start and end time codes go in the header, before they are known (USD reads them only
        // from there), so the header leaves room for them and `commit` rewrites that line.
        let mut header = String::new();
        let _ = writeln!(header, "#usda 1.0\n(");
        let _ = writeln!(header, "    defaultPrim = \"World\"");
        let _ = writeln!(header, "    doc = \"written by hooke: {}\"", escape(name));
        let _ = writeln!(header, "    metersPerUnit = 1\n    upAxis = \"Y\"");
        let _ = writeln!(
            header,
            "    timeCodesPerSecond = {fps}\n    framesPerSecond = {fps}"
        );
        let time_range_at = header.len() as u64;
        let _ = writeln!(header, "{}\n)\n", time_range_line(0.0, 0.0));
        let w = file.writer();
        w.write_all(header.as_bytes())?;
        writeln!(w, "def Xform \"World\"")?;
        writeln!(w, "{{")?;
        writeln!(w, "    def Mesh \"cloth\"")?;
        writeln!(w, "    {{")?;
        writeln!(w, "        uniform bool doubleSided = 1")?;
        writeln!(w, "        uniform token orientation = \"rightHanded\"")?;
        writeln!(w, "        uniform token subdivisionScheme = \"none\"")?;
        let counts = vec!["3"; triangles.len()].join(", ");
        writeln!(w, "        int[] faceVertexCounts = [{counts}]")?;
        let indices: Vec<String> = triangles.iter().flatten().map(u32::to_string).collect();
        writeln!(
            w,
            "        int[] faceVertexIndices = [{}]",
            indices.join(", ")
        )?;
        if let Some(uvs) = uvs {
            write_st(w, uvs, triangles, points)?;
        }
        writeln!(w, "        point3f[] points.timeSamples = {{")?;
        Ok(Self {
            file,
            timing,
            points,
            time_range_at,
            frames: Vec::new(),
        })
    }

    pub(super) fn append(
        &mut self,
        step: u64,
        positions: &[DVec3],
        colliders: &[Collider],
    ) -> std::io::Result<()> {
        if positions.len() != self.points {
            return Err(std::io::Error::other(format!(
                ".usda frame of {} points in a file of {}",
                positions.len(),
                self.points
            )));
        }
        let time = self.timing.time_code(step);
        let mut line = String::with_capacity(40 * positions.len());
        let mut bounds = [Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)];
        for (k, p) in positions.iter().enumerate() {
            let p = p.as_vec3();
            bounds = [bounds[0].min(p), bounds[1].max(p)];
            let separator = if k == 0 { "" } else { ", " };
            let _ = write!(line, "{separator}({}, {}, {})", p.x, p.y, p.z);
        }
        writeln!(self.file.writer(), "            {time}: [{line}],")?;
        self.frames.push((time, bounds, colliders.to_vec()));
        Ok(())
    }

    pub(super) fn commit(mut self) -> std::io::Result<()> {
        let mut tail = String::new();
        tail.push_str("        }\n");
        tail.push_str("        float3[] extent.timeSamples = {\n");
        for (time, [low, high], _) in &self.frames {
            let _ = writeln!(
                tail,
                "            {time}: [({}, {}, {}), ({}, {}, {})],",
                low.x, low.y, low.z, high.x, high.y, high.z
            );
        }
        tail.push_str("        }\n    }\n");
        let collider_count = self.frames.first().map_or(0, |f| f.2.len());
        for k in 0..collider_count {
            let track: Vec<(f64, Shape)> = self
                .frames
                .iter()
                .map(|(t, _, c)| (*t, c[k].shape))
                .collect();
            collider_prim(&mut tail, k, &track);
        }
        tail.push_str("}\n");
        let (start, end) = (
            self.frames.first().map_or(0.0, |f| f.0),
            self.frames.last().map_or(0.0, |f| f.0),
        );
        let w = self.file.writer();
        w.write_all(tail.as_bytes())?;
        w.seek(SeekFrom::Start(self.time_range_at))?;
        w.write_all(time_range_line(start, end).as_bytes())?;
        w.seek(SeekFrom::End(0))?;
        self.file.commit()
    }
}

/// The texture coordinates as the `st` primvar: per vertex when each vertex has one UV, else
/// per face corner through an index array (seams kept).
fn write_st(
    w: &mut dyn Write,
    uvs: &TextureCoordinates,
    triangles: &[[u32; 3]],
    points: usize,
) -> std::io::Result<()> {
    let values: Vec<String> = uvs
        .coordinates
        .iter()
        .map(|[u, v]| format!("({}, {})", *u as f32, *v as f32))
        .collect();
    let per_vertex = uvs.is_per_vertex(triangles, points);
    let interpolation = if per_vertex { "vertex" } else { "faceVarying" };
    writeln!(
        w,
        "        texCoord2f[] primvars:st = [{}] (\n            interpolation = \"{interpolation}\"\n        )",
        values.join(", ")
    )?;
    if !per_vertex {
        let indices: Vec<String> = uvs.corners.iter().flatten().map(u32::to_string).collect();
        writeln!(
            w,
            "        int[] primvars:st:indices = [{}]",
            indices.join(", ")
        )?;
    }
    Ok(())
}

/// The header's time range, each number padded to a fixed width so that the final values can
/// be written over the first ones.
fn time_range_line(start: f64, end: f64) -> String {
    format!("    startTimeCode = {start:<24}\n    endTimeCode = {end:<24}")
}

/// A collider as a USD gprim, its place time-sampled when it moves.
fn collider_prim(out: &mut String, index: usize, track: &[(f64, Shape)]) {
    let Some((_, first)) = track.first() else {
        return;
    };
    // Translation and orientation per frame; the size never changes.
    let placed: Vec<(f64, DVec3, DQuat)> = track
        .iter()
        .map(|(t, shape)| {
            let (center, axis) = match *shape {
                Shape::Sphere { center, .. } => (center, DVec3::Z),
                Shape::Plane { point, normal } => (point, normal),
                Shape::Capsule { start, end, .. } => (0.5 * (start + end), end - start),
            };
            let orient = DQuat::from_rotation_arc(DVec3::Z, axis.normalize_or(DVec3::Z));
            (*t, center, orient)
        })
        .collect();
    let _ = match *first {
        Shape::Sphere { radius, .. } => writeln!(
            out,
            "    def Sphere \"collider_{index}\"\n    {{\n        double radius = {radius}"
        ),
        Shape::Plane { .. } => writeln!(
            out,
            "    def Plane \"collider_{index}\"\n    {{\n        uniform token axis = \"Z\"\n        \
             double width = {PLANE_SIZE}\n        double length = {PLANE_SIZE}\n        \
             uniform bool doubleSided = 1"
        ),
        Shape::Capsule { start, end, radius } => writeln!(
            out,
            "    def Capsule \"collider_{index}\"\n    {{\n        uniform token axis = \"Z\"\n        \
             double radius = {radius}\n        double height = {}",
            start.distance(end)
        ),
    };
    let moves = placed
        .windows(2)
        .any(|w| w[0].1 != w[1].1 || w[0].2 != w[1].2);
    let translate = |c: DVec3| format!("({}, {}, {})", c.x, c.y, c.z);
    let orient = |q: DQuat| {
        format!(
            "({}, {}, {}, {})",
            q.w as f32, q.x as f32, q.y as f32, q.z as f32
        )
    };
    if moves {
        out.push_str("        double3 xformOp:translate.timeSamples = {\n");
        for (t, c, _) in &placed {
            let _ = writeln!(out, "            {t}: {},", translate(*c));
        }
        out.push_str("        }\n        quatf xformOp:orient.timeSamples = {\n");
        for (t, _, q) in &placed {
            let _ = writeln!(out, "            {t}: {},", orient(*q));
        }
        out.push_str("        }\n");
    } else {
        let (_, c, q) = placed[0];
        let _ = writeln!(out, "        double3 xformOp:translate = {}", translate(c));
        let _ = writeln!(out, "        quatf xformOp:orient = {}", orient(q));
    }
    out.push_str(
        "        uniform token[] xformOpOrder = [\"xformOp:translate\", \"xformOp:orient\"]\n    }\n",
    );
}

/// A string for a double-quoted USD string.
fn escape(text: &str) -> String {
    text.replace('\\', "\\\\")
        .replace('"', "\\\"")
        .replace('\n', " ")
}
