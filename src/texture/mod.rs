//! Surface textures by speed modulation (Kanada's "texture mapping"): the head slows where
//! the picture is dark and speeds up where it is light, while the extruder keeps the speed
//! the slicer gave the path, so a slow stretch lays a thicker bead and a fast one a thinner.
//!
//! Input: a G-code text, its config and a [`Spec`] (picture or pattern, how it is mapped onto
//! the surface, speed range, roles). Output: [`Textured`]: the text with the chosen roles'
//! moves cut into texel-sized pieces with their own F and E, every other line as it was, the
//! progress lines and footer updated, and what the texture achieved.
//!
//! Invariants:
//! - Only moves of the chosen roles (default: external perimeters) change; their pieces
//!   follow the move's path (arcs linearised at 0.01 mm).
//! - Constant extrusion (the default): E of each piece = the move's E per second as sliced
//!   (E / (length / F)) x the piece's time *as poa's estimator plans the output* (with the
//!   file's acceleration and jerk), so E per second stays the slicer's along the path
//!   whatever the acceleration does. `--mode velocity` keeps E per mm and changes only F.
//! - Speeds stay within the range; within it, a piece is never wider than twice the nozzle
//!   (its speed is raised until it is not, at most to the top of the range) nor, in velocity
//!   mode, above `--max-flow`; no piece is shorter than the firmware takes at
//!   [`MAX_MOVES_PER_S`].

pub mod font;

use std::collections::HashMap;

use crate::config::SlicerConfig;
use crate::error::Error;
use crate::layers::{LayerKind, LayerReader, ReaderOptions, Role};
use crate::machine::{Action, Machine, Move};
use crate::movemap::{MoveMap, Piece};
use crate::writer::MmPerMin;

/// Most moves per second the texture asks of the firmware: Marlin's and Klipper's planners
/// take several hundred short moves a second from SD or USB; 200 leaves room for both.
pub const MAX_MOVES_PER_S: f64 = 200.0;
/// Largest picture taken (pixels a side).
pub const MAX_IMAGE_SIDE: u32 = 8192;
/// Most pieces a texture writes (each holds about 100 bytes while the file is made).
pub const MAX_PIECES: usize = 5_000_000;

/// Where the darkness of the texture comes from.
#[derive(Debug, Clone)]
pub enum Source {
    /// Dark and light bands across `u`, each half the tile wide.
    Stripes,
    /// Squares of half the tile.
    Checker,
    /// Smooth value noise, features a quarter of the tile.
    Noise,
    /// A darkness bitmap (1 = black), row by row from the top: a picture or rendered text.
    Bitmap { w: usize, h: usize, px: Vec<f32> },
}

impl Source {
    /// A pattern by name (`stripes`, `checker`, `noise`, `text:ABC`).
    pub fn pattern(name: &str) -> Result<Source, Error> {
        Ok(match name {
            "stripes" => Source::Stripes,
            "checker" => Source::Checker,
            "noise" => Source::Noise,
            _ => match name.strip_prefix("text:") {
                Some(t) if !t.is_empty() && t.chars().count() <= 200 => {
                    let (w, h, px) = font::render(t).map_err(|c| {
                        Error::Invalid(format!(
                            "--pattern text: the font has no `{c}` (letters, digits, space and - . ! ? + :)"
                        ))
                    })?;
                    Source::Bitmap { w, h, px }
                }
                Some(_) => {
                    return Err(Error::Invalid(
                        "--pattern text: needs 1 to 200 characters, e.g. text:POA".into(),
                    ))
                }
                None => {
                    return Err(Error::Invalid(format!(
                    "unknown pattern `{name}`; the patterns are stripes, checker, noise, text:ABC"
                )))
                }
            },
        })
    }

    /// A PNG picture; darkness = 1 - luminance (alpha over white).
    pub fn png(data: &[u8]) -> Result<Source, Error> {
        let bad = |why: String| Error::Invalid(format!("--image: {why}"));
        // The size, from the header, before the decoder sees anything.
        if data.len() >= 24 && data.starts_with(b"\x89PNG\r\n\x1a\n") && &data[12..16] == b"IHDR" {
            let w = u32::from_be_bytes([data[16], data[17], data[18], data[19]]);
            let h = u32::from_be_bytes([data[20], data[21], data[22], data[23]]);
            if w == 0 || h == 0 {
                return Err(bad(format!("the picture is {w} x {h} pixels")));
            }
            if w > MAX_IMAGE_SIDE || h > MAX_IMAGE_SIDE {
                return Err(bad(format!(
                    "the picture is {w} x {h} pixels, more than {MAX_IMAGE_SIDE} a side; scale it down"
                )));
            }
        }
        let mut decoder = png::Decoder::new_with_limits(
            std::io::Cursor::new(data),
            png::Limits {
                bytes: 256 * 1024 * 1024,
            },
        );
        decoder.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
        let mut reader = decoder
            .read_info()
            .map_err(|e| bad(format!("not a PNG picture poa can read ({e})")))?;
        let (w, h) = (reader.info().width, reader.info().height);
        let mut buf = vec![0u8; reader.output_buffer_size()];
        let frame = reader
            .next_frame(&mut buf)
            .map_err(|e| bad(format!("the picture's data is damaged ({e})")))?;
        let channels = frame.color_type.samples();
        let (w, h) = (w as usize, h as usize);
        let mut px = Vec::with_capacity(w * h);
        for i in 0..w * h {
            let p = &buf[i * channels..(i + 1) * channels];
            let (lum, alpha) = match channels {
                1 => (p[0] as f32, 255.0),
                2 => (p[0] as f32, p[1] as f32),
                3 => (
                    0.2126 * p[0] as f32 + 0.7152 * p[1] as f32 + 0.0722 * p[2] as f32,
                    255.0,
                ),
                _ => (
                    0.2126 * p[0] as f32 + 0.7152 * p[1] as f32 + 0.0722 * p[2] as f32,
                    p[3] as f32,
                ),
            };
            let a = alpha / 255.0;
            let over_white = lum / 255.0 * a + (1.0 - a);
            px.push(1.0 - over_white);
        }
        Ok(Source::Bitmap { w, h, px })
    }

    /// Aspect (width / height) of a bitmap source.
    fn aspect(&self) -> Option<f64> {
        match self {
            Source::Bitmap { w, h, .. } => Some(*w as f64 / *h as f64),
            _ => None,
        }
    }

    /// Darkness in [0, 1] at (`a`, `b`), shares of the tile (0..1, `b` = 0 at the bottom).
    fn value(&self, a: f64, b: f64) -> f64 {
        match self {
            Source::Stripes => f64::from(u8::from(a < 0.5)),
            Source::Checker => f64::from(u8::from((a < 0.5) != (b < 0.5))),
            Source::Noise => noise(a * 4.0, b * 4.0, 4),
            Source::Bitmap { w, h, px } => {
                // Bilinear, pixel centres at half steps, tiled.
                let x = a * *w as f64 - 0.5;
                let y = (1.0 - b) * *h as f64 - 0.5;
                let (x0, y0) = (x.floor(), y.floor());
                let (fx, fy) = (x - x0, y - y0);
                let at = |i: f64, j: f64| {
                    let i = (i as i64).rem_euclid(*w as i64) as usize;
                    let j = (j as i64).rem_euclid(*h as i64) as usize;
                    px[j * *w + i] as f64
                };
                let top = at(x0, y0) * (1.0 - fx) + at(x0 + 1.0, y0) * fx;
                let bottom = at(x0, y0 + 1.0) * (1.0 - fx) + at(x0 + 1.0, y0 + 1.0) * fx;
                top * (1.0 - fy) + bottom * fy
            }
        }
    }
}

/// Smooth value noise on a lattice of `period` cells (tiles seamlessly), in [0, 1].
fn noise(x: f64, y: f64, period: i64) -> f64 {
    let lattice = |i: i64, j: i64| -> f64 {
        let (i, j) = (i.rem_euclid(period) as u64, j.rem_euclid(period) as u64);
        // A small integer hash (splitmix64's finaliser) of the cell.
        let mut z = i.wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ j.wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    };
    let (x0, y0) = (x.floor(), y.floor());
    let s = |t: f64| t * t * (3.0 - 2.0 * t);
    let (fx, fy) = (s(x - x0), s(y - y0));
    let (i, j) = (x0 as i64, y0 as i64);
    let top = lattice(i, j) * (1.0 - fx) + lattice(i + 1, j) * fx;
    let bottom = lattice(i, j + 1) * (1.0 - fx) + lattice(i + 1, j + 1) * fx;
    top * (1.0 - fy) + bottom * fy
}

/// How the picture's (u, v) in mm is laid on the part.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mapping {
    /// u = angle around the centre x the mean radius of the textured walls, v = z.
    Cylindrical,
    /// u = x, v = z (seen along Y).
    PlanarX,
    /// u = y, v = z (seen along X).
    PlanarY,
    /// u = angle around the centre x mean radius, v = polar angle from the top about the
    /// centre at mid-height x mean radius.
    Spherical,
    /// u = length along each loop from where it crosses the +X ray from the centre (counter-
    /// clockwise), the tile stretched so that a whole number of tiles goes round: no seam.
    Wrap,
}

impl Mapping {
    pub fn parse(name: &str) -> Result<Mapping, Error> {
        Ok(match name {
            "cylindrical" => Mapping::Cylindrical,
            "planar-x" => Mapping::PlanarX,
            "planar-y" => Mapping::PlanarY,
            "spherical" => Mapping::Spherical,
            "wrap" => Mapping::Wrap,
            _ => {
                return Err(Error::Invalid(format!(
                "unknown mapping `{name}`; the mappings are cylindrical, planar-x, planar-y, spherical, wrap"
            )))
            }
        })
    }
}

/// Constant extrusion (the paper) or constant E per mm (the velocity-painting scripts).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    Constant,
    Velocity,
}

/// What the user asked for.
#[derive(Debug, Clone)]
pub struct Spec {
    pub source: Source,
    pub mapping: Mapping,
    /// Tile size (mm); `None`: 20 mm high, as wide as the picture's aspect (20 for patterns).
    pub size: Option<[f64; 2]>,
    pub offset: [f64; 2],
    /// Slowest and fastest head speed (mm/s): darkest and lightest.
    pub speeds: [f64; 2],
    pub roles: Vec<Role>,
    pub invert: bool,
    pub mode: Mode,
    /// Volumetric flow cap (mm3/s) in velocity mode; `None`: the profile's, else 15.
    pub max_flow: Option<f64>,
    /// Centre of cylindrical and spherical mappings; `None`: the textured walls' own.
    pub center: Option<[f64; 2]>,
}

impl Spec {
    fn tile(&self) -> [f64; 2] {
        self.size.unwrap_or_else(|| {
            let h = 20.0;
            [self.source.aspect().map_or(20.0, |a| h * a), h]
        })
    }
}

/// Reads a role list (`external-perimeter,perimeter`, slicer names too).
pub fn parse_roles(text: &str) -> Result<Vec<Role>, Error> {
    let mut roles = Vec::new();
    for name in text.split(',').map(str::trim).filter(|n| !n.is_empty()) {
        let spaced = name.replace(['-', '_'], " ");
        let role = Role::ALL
            .iter()
            .copied()
            .find(|r| r.name() == spaced)
            .or_else(|| Role::from_slicer_name(&spaced))
            .or_else(|| Role::from_slicer_name(name))
            .ok_or_else(|| {
                Error::Invalid(format!(
                    "--roles: unknown role `{name}` (e.g. external-perimeter, perimeter, overhang-perimeter)"
                ))
            })?;
        if !roles.contains(&role) {
            roles.push(role);
        }
    }
    if roles.is_empty() {
        return Err(Error::Invalid(
            "--roles is empty: name at least one role, e.g. external-perimeter".into(),
        ));
    }
    Ok(roles)
}

/// Where a textured segment lies on its loop (for the wrap mapping) and how high its bead is.
#[derive(Debug, Clone, Copy)]
struct Seg {
    /// Length along the loop (counter-clockwise from the +X ray) where the segment starts.
    u0: f64,
    /// +1 when the loop runs counter-clockwise, -1 clockwise.
    dir: f64,
    loop_len: f64,
    height: f64,
}

/// The textured lines of a file and the surface they make.
struct Survey {
    segs: HashMap<u64, Seg>,
    /// Length of the walls to texture (mm).
    length: f64,
    center: [f64; 2],
    radius: f64,
    z_mid: f64,
}

/// The closed loops of a layer without role information that no other closed loop of the
/// layer encloses (by bounding box): each island's outer wall.
fn outermost_loops(paths: &[crate::layers::Path]) -> Vec<crate::layers::Path> {
    if paths.iter().any(|p| p.role != Role::Unknown) {
        return Vec::new();
    }
    let boxes: Vec<Option<[f64; 4]>> = paths
        .iter()
        .map(|p| {
            let (a, b) = (p.points.first()?, p.points.last()?);
            let closed =
                (a[0] - b[0]).hypot(a[1] - b[1]) <= 2.0 * p.width.max(0.2) && p.length() > 5.0;
            closed.then(|| {
                p.points.iter().fold(
                    [
                        f64::INFINITY,
                        f64::INFINITY,
                        f64::NEG_INFINITY,
                        f64::NEG_INFINITY,
                    ],
                    |r, q| {
                        [
                            r[0].min(q[0]),
                            r[1].min(q[1]),
                            r[2].max(q[0]),
                            r[3].max(q[1]),
                        ]
                    },
                )
            })
        })
        .collect();
    let inside = |a: &[f64; 4], b: &[f64; 4]| {
        a[0] >= b[0] - 1e-6 && a[1] >= b[1] - 1e-6 && a[2] <= b[2] + 1e-6 && a[3] <= b[3] + 1e-6
    };
    // A skirt encloses loops but none of them closely (a wall's inner perimeter lies a width
    // inside it): it is not a wall, and the loops inside it are candidates.
    let gap = |a: &[f64; 4], b: &[f64; 4]| {
        (b[0] - a[0])
            .min(b[1] - a[1])
            .min(a[2] - b[2])
            .min(a[3] - b[3])
    };
    let boxes: Vec<Option<[f64; 4]>> = boxes
        .iter()
        .enumerate()
        .map(|(i, a)| {
            let a = (*a)?;
            let w = paths[i].width.max(0.2);
            let enclosed: Vec<f64> = boxes
                .iter()
                .enumerate()
                .filter_map(|(j, b)| b.filter(|b| j != i && inside(b, &a) && *b != a))
                .map(|b| gap(&a, &b))
                .collect();
            let skirt = !enclosed.is_empty() && enclosed.iter().all(|g| *g > 3.0 * w);
            (!skirt).then_some(a)
        })
        .collect();
    paths
        .iter()
        .zip(&boxes)
        .enumerate()
        .filter(|(i, (_, bx))| {
            bx.as_ref().is_some_and(|a| {
                !boxes
                    .iter()
                    .enumerate()
                    .any(|(j, b)| j != *i && b.as_ref().is_some_and(|b| inside(a, b) && a != b))
            })
        })
        .map(|(_, (p, _))| p.clone())
        .collect()
}

/// Finds the moves of `roles` (by source line) and the walls they make.
fn survey(text: &[u8], config: &SlicerConfig, roles: &[Role]) -> Result<Survey, Error> {
    let reader = LayerReader::new(
        text,
        ReaderOptions {
            keep_raw: false,
            config: config.clone(),
        },
    );
    let mut paths: Vec<crate::layers::Path> = Vec::new();
    // Files without role comments: each layer's outermost closed loops stand for the
    // external perimeters (kept aside until the file turns out to have no roles at all).
    let mut outermost: Vec<crate::layers::Path> = Vec::new();
    let fallback = roles.contains(&Role::ExternalPerimeter);
    for layer in reader {
        let layer = layer.map_err(|e| Error::Invalid(format!("cannot read the file: {e}")))?;
        if layer.kind != LayerKind::Layer {
            continue;
        }
        // (Not on the first layer: a skirt of several loops, a brim, surround the part there.)
        if fallback && paths.is_empty() && layer.index > 0 {
            outermost.extend(outermost_loops(&layer.paths));
        }
        paths.extend(
            layer
                .paths
                .into_iter()
                .filter(|p| roles.contains(&p.role) && p.points.len() >= 2),
        );
    }
    if paths.is_empty() {
        paths = outermost;
    }
    if paths.is_empty() {
        let names: Vec<&str> = roles.iter().map(|r| r.name()).collect();
        return Err(Error::Invalid(format!(
            "nothing to texture: the file has no {} (slice with comments, e.g. PrusaSlicer's gcode_comments or Cura's ;TYPE lines, or choose --roles)",
            names.join(" or ")
        )));
    }
    // The walls' centre (middle of their box) and mean radius about it.
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for p in &paths {
        for q in &p.points {
            for i in 0..2 {
                lo[i] = lo[i].min(q[i]);
                hi[i] = hi[i].max(q[i]);
            }
        }
        lo[2] = lo[2].min(p.z);
        hi[2] = hi[2].max(p.z);
    }
    let center = [(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0];
    let (mut rs, mut n) = (0.0f64, 0.0f64);
    for p in &paths {
        for q in &p.points {
            rs += (q[0] - center[0]).hypot(q[1] - center[1]);
            n += 1.0;
        }
    }
    let mut segs = HashMap::new();
    for p in &paths {
        let pts = &p.points;
        let len: f64 = pts
            .windows(2)
            .map(|w| (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]))
            .sum();
        if len <= 0.0 {
            continue;
        }
        // Orientation (shoelace) and the point nearest the +X ray from the centre.
        let area2: f64 = pts
            .windows(2)
            .map(|w| w[0][0] * w[1][1] - w[1][0] * w[0][1])
            .sum::<f64>()
            + (pts[pts.len() - 1][0] * pts[0][1] - pts[0][0] * pts[pts.len() - 1][1]);
        let dir = if area2 >= 0.0 { 1.0 } else { -1.0 };
        let mut acc = 0.0;
        let mut origin = (f64::INFINITY, 0.0);
        let mut starts = Vec::with_capacity(pts.len());
        for w in pts.windows(2) {
            starts.push(acc);
            let a = (w[0][1] - center[1]).atan2(w[0][0] - center[0]).abs();
            if a < origin.0 {
                origin = (a, acc);
            }
            acc += (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]);
        }
        for (i, line) in p.seg_line.iter().enumerate() {
            let from_origin = (starts[i] - origin.1).rem_euclid(len);
            let u0 = if dir > 0.0 {
                from_origin
            } else {
                (len - from_origin).rem_euclid(len)
            };
            // A move's first segment stands for the move (arcs come as several).
            segs.entry(*line).or_insert(Seg {
                u0,
                dir,
                loop_len: len,
                height: p.height,
            });
        }
    }
    Ok(Survey {
        length: paths.iter().map(|p| p.length()).sum(),
        segs,
        center,
        radius: (rs / n.max(1.0)).max(1e-3),
        z_mid: (lo[2] + hi[2]) / 2.0,
    })
}

/// One piece the map wrote: where it ends, its length, the move's E per second and per mm,
/// where it lies on the picture and the speed asked.
#[derive(Debug, Clone, Copy)]
pub struct PieceRec {
    pub to: [f64; 3],
    pub length: f64,
    pub rate: f64,
    pub per_mm: f64,
    pub uv: [f64; 2],
    pub darkness: f64,
    pub target: f64,
    pub height: f64,
}

/// The move map that cuts textured moves into pieces.
struct TextureMap<'a> {
    spec: &'a Spec,
    survey: &'a Survey,
    tile: [f64; 2],
    piece_len: f64,
    nozzle: f64,
    filament_area: f64,
    max_flow: f64,
    /// E of each piece, in order, once the estimator has timed them (constant mode).
    final_e: Option<&'a [f64]>,
    pieces: Vec<PieceRec>,
}

impl TextureMap<'_> {
    /// (u, v) in mm of point `p` of a move of segment `seg`, `along` mm into the move.
    fn uv(&self, p: [f64; 3], seg: &Seg, along: f64) -> [f64; 2] {
        let c = self.spec.center.unwrap_or(self.survey.center);
        let r = self.survey.radius;
        let theta = (p[1] - c[1]).atan2(p[0] - c[0]);
        match self.spec.mapping {
            Mapping::Cylindrical => [(theta + std::f64::consts::PI) * r, p[2]],
            Mapping::PlanarX => [p[0], p[2]],
            Mapping::PlanarY => [p[1], p[2]],
            Mapping::Spherical => {
                let rho = (p[0] - c[0]).hypot(p[1] - c[1]);
                let phi = rho.atan2(p[2] - self.survey.z_mid);
                [
                    (theta + std::f64::consts::PI) * r,
                    (std::f64::consts::PI - phi) * r,
                ]
            }
            Mapping::Wrap => {
                let u = (seg.u0 + seg.dir * along).rem_euclid(seg.loop_len);
                // Whole tiles round the loop: the tile is stretched to fit.
                let tiles = (seg.loop_len / self.tile[0]).round().max(1.0);
                [u * self.tile[0] * tiles / seg.loop_len, p[2]]
            }
        }
    }

    fn darkness(&self, uv: [f64; 2]) -> f64 {
        let a = ((uv[0] - self.spec.offset[0]) / self.tile[0]).rem_euclid(1.0);
        let b = ((uv[1] - self.spec.offset[1]) / self.tile[1]).rem_euclid(1.0);
        let d = self.spec.source.value(a, b).clamp(0.0, 1.0);
        if self.spec.invert {
            1.0 - d
        } else {
            d
        }
    }
}

impl MoveMap for TextureMap<'_> {
    fn map(&mut self, m: &Move, _before: &Machine, out: &mut Vec<Piece>) {
        let Some(seg) = self.survey.segs.get(&m.line).copied() else {
            out.push(Piece::unchanged(m));
            return;
        };
        if !m.is_extrusion() || m.feed <= 0.0 {
            out.push(Piece::unchanged(m));
            return;
        }
        let pts = m.points(0.01);
        let total = crate::geometry::polyline_length(&pts);
        if total <= 1e-6 {
            out.push(Piece::unchanged(m));
            return;
        }
        let per_mm = m.e / total;
        let rate = per_mm * m.feed / 60.0;
        let h = seg.height.max(0.01);
        let [low, high] = self.spec.speeds;
        // Slowest speed that keeps the bead within twice the nozzle (constant extrusion).
        let widest = (2.0 * self.nozzle - h * (1.0 - std::f64::consts::FRAC_PI_4)).max(h) * h;
        let floor = rate * self.filament_area / widest;
        // Fastest speed within the flow cap (velocity mode).
        let ceiling = self.max_flow / (per_mm * self.filament_area).max(1e-9);
        let z = |f: f64| m.from[2] + (m.to[2] - m.from[2]) * f;
        let mut along = 0.0;
        for w in pts.windows(2) {
            let l = (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]);
            if l < 1e-6 {
                // A repeated point of the slicer's path: no piece of its own.
                continue;
            }
            let n = ((l / self.piece_len).ceil() as usize).clamp(1, 100_000);
            for i in 0..n {
                let (f0, f1) = (i as f64 / n as f64, (i + 1) as f64 / n as f64);
                let at = |f: f64| {
                    [
                        w[0][0] + (w[1][0] - w[0][0]) * f,
                        w[0][1] + (w[1][1] - w[0][1]) * f,
                    ]
                };
                let (a, b) = (at(f0), at(f1));
                let len = l / n as f64;
                let mid_along = along + len / 2.0;
                let mid = [
                    (a[0] + b[0]) / 2.0,
                    (a[1] + b[1]) / 2.0,
                    z(mid_along / total),
                ];
                let uv = self.uv(mid, &seg, mid_along);
                let darkness = self.darkness(uv);
                let mut v = high - darkness * (high - low);
                let (e, v) = match self.spec.mode {
                    Mode::Constant => {
                        // The width cap raises the speed, never past the range.
                        v = v.max(floor).min(high);
                        let e = match self.final_e {
                            Some(es) => {
                                es.get(self.pieces.len()).copied().unwrap_or(rate * len / v)
                            }
                            None => rate * len / v,
                        };
                        (e, v)
                    }
                    Mode::Velocity => {
                        v = v.min(ceiling);
                        (per_mm * len, v)
                    }
                };
                along += len;
                let to = [b[0], b[1], z(along / total)];
                self.pieces.push(PieceRec {
                    to,
                    length: len,
                    rate,
                    per_mm,
                    uv,
                    darkness,
                    target: v,
                    height: h,
                });
                out.push(Piece {
                    to,
                    e,
                    feed: MmPerMin(v * 60.0),
                });
            }
        }
        // The last piece ends exactly where the move did.
        match out.last_mut() {
            Some(last) => last.to = m.to,
            None => out.push(Piece::unchanged(m)),
        }
    }
}

/// What [`texture_text`] made.
pub struct Textured {
    pub text: Vec<u8>,
    pub pieces: Vec<PieceRec>,
    /// Time (s) of each piece as poa's estimator plans the output.
    pub times: Vec<f64>,
    pub lines_rewritten: u64,
    pub time_in: f64,
    pub time_out: f64,
    pub filament_in: f64,
    pub filament_out: f64,
    /// Acceleration the contrast report assumes (mm/s2): the file's for extrusion.
    pub acceleration: f64,
    pub piece_len: f64,
    pub tile: [f64; 2],
}

impl Textured {
    /// Shortest texel (mm) in which the head can change between the two speeds at the file's
    /// acceleration: (high^2 - low^2) / (2 a).
    pub fn min_texel(&self, speeds: [f64; 2]) -> f64 {
        (speeds[1].powi(2) - speeds[0].powi(2)).abs() / (2.0 * self.acceleration.max(1.0))
    }

    /// Slowest and fastest speed the head reaches on a piece (length / planned time).
    pub fn achieved(&self) -> [f64; 2] {
        let mut r = [f64::INFINITY, 0.0f64];
        for (p, t) in self.pieces.iter().zip(&self.times) {
            if *t > 0.0 {
                let v = p.length / t;
                r = [r[0].min(v), r[1].max(v)];
            }
        }
        r
    }
}

/// Per-line end times of `text` by poa's estimator: (line, time at the end of its move).
fn line_times(text: &[u8], config: &SlicerConfig) -> Vec<(u64, f64)> {
    let mut est = crate::estimate::Estimator::new(crate::estimate::Limits::from_config(config))
        .with_marks(1e-9);
    let mut machine = Machine::new();
    crate::estimate::feed_text(&mut est, &mut machine, text, 0);
    est.finish().1
}

/// Time (s) of each of `pieces` in `text`, which holds them in order among other moves.
fn piece_times(text: &[u8], config: &SlicerConfig, pieces: &[PieceRec]) -> Option<Vec<f64>> {
    let marks = line_times(text, config);
    let mut machine = Machine::new();
    let mut times = Vec::with_capacity(pieces.len());
    for (i, raw) in crate::gcode::split_lines(text).enumerate() {
        if times.len() == pieces.len() {
            break;
        }
        let parsed = crate::gcode::parse_line(crate::gcode::strip_terminator(raw));
        let line = i as u64 + 1;
        let Action::Move(m) = machine.step(&parsed, line) else {
            continue;
        };
        let p = &pieces[times.len()];
        // By where it ends: a piece so short that its E rounds to 0 is still a piece.
        if !(0..3).all(|k| (m.to[k] - p.to[k]).abs() < 0.002) {
            continue;
        }
        // A move the estimator gave no time (no block) took none.
        let j = marks.partition_point(|(l, _)| *l < line);
        let time = match marks.get(j) {
            Some((l, end)) if *l == line => end - if j > 0 { marks[j - 1].1 } else { 0.0 },
            _ => 0.0,
        };
        times.push(time);
    }
    (times.len() == pieces.len()).then_some(times)
}

/// Textures `text` by `spec` (see the module doc).
/// `totals`: the print times the file's progress lines were computed against
/// ([`crate::progress::Totals::of`] for a slicer's file).
pub fn texture_text(
    text: &[u8],
    config: &SlicerConfig,
    spec: &Spec,
    totals: crate::progress::Totals,
) -> Result<Textured, Error> {
    let [low, high] = spec.speeds;
    if !(low.is_finite() && high.is_finite() && low > 0.0 && low <= high && high <= 1000.0) {
        return Err(Error::Invalid(format!(
            "--speed-range {low},{high}: give LOW,HIGH mm/s with 0 < LOW <= HIGH <= 1000"
        )));
    }
    let tile = spec.tile();
    if !(tile
        .iter()
        .all(|t| t.is_finite() && (0.1..=10_000.0).contains(t)))
    {
        return Err(Error::Invalid(format!(
            "--size {},{}: each side between 0.1 and 10000 mm",
            tile[0], tile[1]
        )));
    }
    if !spec.offset.iter().all(|o| o.is_finite()) {
        return Err(Error::Invalid("--offset must be two numbers".into()));
    }
    let survey = survey(text, config, &spec.roles)?;
    let limits = crate::estimate::Limits::from_config(config);
    let acceleration = limits.extruding.max(1.0);
    // Texel: an eighth of the tile's smaller side, a pixel of the picture, never shorter
    // than the firmware takes at the top speed.
    let texel = match &spec.source {
        Source::Bitmap { w, h, .. } => (tile[0] / *w as f64).min(tile[1] / *h as f64),
        _ => tile[0].min(tile[1]) / 16.0,
    };
    let piece_len = texel.max(high / MAX_MOVES_PER_S).max(0.05);
    // Memory follows the pieces (the output is made in memory): refuse a texture finer than
    // the file can hold, before making it.
    let pieces = (survey.length / piece_len).ceil();
    if pieces > MAX_PIECES as f64 {
        return Err(Error::Invalid(format!(
            "the texture would cut {:.0} mm of walls into {pieces:.0} pieces of {piece_len:.2} mm, more than {MAX_PIECES}; give a larger --size or fewer --roles",
            survey.length
        )));
    }
    let max_flow = spec
        .max_flow
        .or_else(|| {
            config
                .number("filament_max_volumetric_speed")
                .filter(|v| *v > 0.0)
        })
        .unwrap_or(15.0);
    let run = |final_e: Option<&[f64]>| -> Result<(Vec<u8>, Vec<PieceRec>, u64), Error> {
        let mut map = TextureMap {
            spec,
            survey: &survey,
            tile,
            piece_len,
            nozzle: config.nozzle_diameter(),
            filament_area: config.e_area(),
            max_flow,
            final_e,
            pieces: Vec::new(),
        };
        let mut out = Vec::with_capacity(text.len() * 2);
        let stats = crate::movemap::apply(text, &mut map, &crate::writer::Cartesian, &mut out)?;
        Ok((out, map.pieces, stats.rewritten))
    };
    let (first, pieces, lines) = run(None)?;
    let times = piece_times(&first, config, &pieces).ok_or_else(|| {
        Error::Refused(
            "could not time the textured pieces in the output (a move map fault); nothing written"
                .into(),
        )
    })?;
    let mapped = match spec.mode {
        Mode::Velocity => first,
        Mode::Constant => {
            drop(first);
            // E from the time the estimator gives each piece: E per second stays the
            // slicer's whatever acceleration does to the speed.
            let e: Vec<f64> = pieces.iter().zip(&times).map(|(p, t)| p.rate * t).collect();
            run(Some(&e))?.0
        }
    };
    let done = crate::progress::refresh(text, mapped, config, totals)?;
    Ok(Textured {
        text: done.text,
        pieces,
        times,
        lines_rewritten: lines,
        time_in: done.time_in,
        time_out: done.time_out,
        filament_in: done.filament_in,
        filament_out: done.filament_out,
        acceleration,
        piece_len,
        tile,
    })
}

impl Textured {
    /// E of piece `k` as written.
    pub fn e(&self, k: usize, mode: Mode) -> f64 {
        let p = &self.pieces[k];
        match mode {
            Mode::Constant => p.rate * self.times[k],
            Mode::Velocity => p.per_mm * p.length,
        }
    }

    /// Bead width (mm) piece `k` lays, by the flow model.
    pub fn width(&self, k: usize, mode: Mode, filament_area: f64) -> f64 {
        let p = &self.pieces[k];
        crate::layers::flow_width(self.e(k, mode), p.length, p.height, filament_area)
    }
}

/// The output's layer nearest the middle of the textured height, drawn like `poa preview`
/// (strands at the width their E makes, over the area of the layer below).
fn layer_view(t: &Textured, title: &str) -> Option<String> {
    let mut zs: Vec<f64> = t.pieces.iter().map(|p| p.to[2]).collect();
    if zs.is_empty() {
        return None;
    }
    let mid = zs.len() / 2;
    let z = *zs.select_nth_unstable_by(mid, f64::total_cmp).1;
    let config = SlicerConfig::parse(&t.text);
    let reader = LayerReader::new(
        &t.text[..],
        ReaderOptions {
            keep_raw: false,
            config,
        },
    );
    let mut below: Option<crate::layers::Layer> = None;
    for layer in reader {
        let layer = layer.ok()?;
        if layer.kind != LayerKind::Layer {
            continue;
        }
        if (layer.z - z).abs() < 1e-6 {
            let area = below
                .as_ref()
                .map(|b| crate::geometry::printed_area(b, &crate::geometry::AreaOptions::default()))
                .unwrap_or_else(|| geo::MultiPolygon::new(Vec::new()));
            return Some(crate::preview::render(&crate::preview::Scene {
                title,
                layer: &layer,
                below: &area,
                regions: &[],
                samples: &[],
                poa_blocks: &[],
            }));
        }
        below = Some(layer);
    }
    None
}

/// An HTML page: the texture as asked (darkness over the surface, unwrapped: u right, v up)
/// beside the bead width the output lays there (darker = wider), acceleration's blur
/// included since widths come from the estimator's timing.
pub fn preview_page(t: &Textured, spec: &Spec, filament_area: f64, title: &str) -> String {
    use std::fmt::Write as _;
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for p in &t.pieces {
        for i in 0..2 {
            lo[i] = lo[i].min(p.uv[i]);
            hi[i] = hi[i].max(p.uv[i]);
        }
    }
    if t.pieces.is_empty() {
        lo = [0.0; 2];
        hi = [1.0; 2];
    }
    let span = [(hi[0] - lo[0]).max(1.0), (hi[1] - lo[1]).max(1.0)];
    let px = 600.0 / span[0].max(span[1]);
    let (w, h) = (span[0] * px, span[1] * px);
    let widths: Vec<f64> = (0..t.pieces.len())
        .map(|k| t.width(k, spec.mode, filament_area))
        .collect();
    let (wmin, wmax) = widths
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(a, b), x| (a.min(*x), b.max(*x)));
    let shade = |d: f64| {
        let g = (255.0 * (1.0 - d.clamp(0.0, 1.0))).round() as u8;
        format!("#{g:02x}{g:02x}{g:02x}")
    };
    let mut asked = String::new();
    let mut made = String::new();
    for (k, p) in t.pieces.iter().enumerate() {
        let x = (p.uv[0] - lo[0]) * px;
        let y = h - (p.uv[1] - lo[1]) * px;
        let rw = (p.length * px).max(0.5);
        let rh = (p.height * px).max(0.5);
        let _ = write!(
            asked,
            r#"<rect x="{x:.1}" y="{:.1}" width="{rw:.1}" height="{rh:.1}" fill="{}"/>"#,
            y - rh / 2.0,
            shade(p.darkness)
        );
        let d = if wmax > wmin {
            (widths[k] - wmin) / (wmax - wmin)
        } else {
            0.5
        };
        let _ = write!(
            made,
            r#"<rect x="{x:.1}" y="{:.1}" width="{rw:.1}" height="{rh:.1}" fill="{}"/>"#,
            y - rh / 2.0,
            shade(d)
        );
    }
    let [vmin, vmax] = t.achieved();
    let svg = |body: &str| {
        format!(
            r##"<svg xmlns="http://www.w3.org/2000/svg" width="{w:.0}" height="{h:.0}" viewBox="0 0 {w:.1} {h:.1}"><rect width="100%" height="100%" fill="#fff"/>{body}</svg>"##
        )
    };
    let layer = layer_view(t, title).unwrap_or_default();
    format!(
        "<!doctype html>\n<html><head><meta charset=\"utf-8\"><title>{t}</title><style>body{{font-family:sans-serif;margin:1em}} figure{{display:inline-block;margin:0 1em 1em 0;vertical-align:top}} figure.layer svg{{width:600px;height:auto}}</style></head><body>\n<h1>{t}</h1>\n<p>{n} pieces; speeds asked {lo_v}-{hi_v} mm/s, reached {vmin:.1}-{vmax:.1} mm/s at {a:.0} mm/s2 (the smallest texel that shows the full contrast: {texel:.2} mm); bead {wmin:.3}-{wmax:.3} mm wide.</p>\n<figure>{asked}<figcaption>the texture asked (dark = slow), unwrapped: u right, v up</figcaption></figure>\n<figure>{made}<figcaption>bead width the output lays (dark = wide)</figcaption></figure>\n<figure class=\"layer\">{layer}<figcaption>a layer of the output half way up the texture, each strand at the width its E makes</figcaption></figure>\n</body></html>\n",
        t = crate::preview::escape(title),
        n = t.pieces.len(),
        lo_v = spec.speeds[0],
        hi_v = spec.speeds[1],
        a = t.acceleration,
        texel = t.min_texel(spec.speeds),
        asked = svg(&asked),
        made = svg(&made),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn patterns_tile_and_noise_stays_in_range() {
        let s = Source::Stripes;
        assert_eq!(s.value(0.2, 0.5), 1.0);
        assert_eq!(s.value(0.7, 0.5), 0.0);
        let c = Source::Checker;
        assert_eq!(c.value(0.2, 0.2), 0.0);
        assert_eq!(c.value(0.7, 0.2), 1.0);
        for i in 0..100 {
            let v = noise(i as f64 * 0.37, i as f64 * 0.11, 4);
            assert!((0.0..=1.0).contains(&v));
        }
        // Seamless: the lattice repeats every period.
        assert!((noise(0.3, 0.6, 4) - noise(4.3, 4.6, 4)).abs() < 1e-12);
    }

    #[test]
    fn repeated_points_and_moves_too_short_for_their_e_are_still_textured() {
        // Cura writes repeated points and hair-thin moves into walls: a piece of length 0
        // or with E rounding to 0 must not stop the pieces from being timed.
        let mut text = String::from(";FLAVOR:Marlin\nM83\nG28\n");
        for layer in 0..3 {
            let z = 0.2 * (layer + 1) as f64;
            text.push_str(&format!(
                ";LAYER:{layer}\nG0 Z{z:.1} F600\nG0 X10 Y10 F6000\n;TYPE:WALL-OUTER\n"
            ));
            text.push_str("G1 F1500 X30 Y10 E0.7\nG1 X30 Y10 E0.0001\nG1 X30 Y30 E0.7\n");
            text.push_str("G1 X30.0004 Y30 E0.00001\nG1 X10 Y30 E0.7\nG1 X10 Y10 E0.7\n");
        }
        let config = SlicerConfig::parse(text.as_bytes());
        let spec = Spec {
            source: Source::Checker,
            mapping: Mapping::Wrap,
            size: Some([4.0, 0.4]),
            offset: [0.0, 0.0],
            speeds: [15.0, 40.0],
            roles: vec![Role::ExternalPerimeter],
            invert: false,
            mode: Mode::Constant,
            max_flow: None,
            center: None,
        };
        let t = texture_text(
            text.as_bytes(),
            &config,
            &spec,
            crate::progress::Totals::default(),
        )
        .unwrap();
        assert!(t.pieces.len() > 3 * 4 * 16, "{} pieces", t.pieces.len());
        assert_eq!(t.times.len(), t.pieces.len());
    }

    #[test]
    fn roles_and_mappings_are_read_or_refused_by_name() {
        assert_eq!(
            parse_roles("external-perimeter, perimeter").unwrap(),
            vec![Role::ExternalPerimeter, Role::Perimeter]
        );
        assert_eq!(
            parse_roles("WALL-OUTER").unwrap(),
            vec![Role::ExternalPerimeter]
        );
        assert!(parse_roles("").is_err());
        assert!(parse_roles("walls")
            .unwrap_err()
            .to_string()
            .contains("walls"));
        assert_eq!(Mapping::parse("wrap").unwrap(), Mapping::Wrap);
        assert!(Mapping::parse("cube").is_err());
        assert!(Source::pattern("text:").is_err());
        assert!(Source::pattern("zigzag").is_err());
    }
}
