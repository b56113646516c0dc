//! Stage 3: the layer model, whatever slicer wrote the file.
//!
//! Input: a byte stream of G-code (read through [`crate::gcode`] and interpreted by
//! [`crate::machine`]) plus the file's [`SlicerConfig`]. Output: an iterator of [`Layer`]s in
//! file order, each with its Z, height, extrusion [`Path`]s (polyline, width, height, role,
//! object, source lines) and, on request, its raw bytes.
//!
//! Invariants:
//! - Streaming: one layer is built at a time; memory does not grow with the file.
//! - Every input line belongs to exactly one emitted [`Layer`] (the preamble before the first
//!   layer is a [`LayerKind::Preamble`] block), in order, so concatenating `raw` of all layers
//!   reproduces the input byte for byte when `keep_raw` is on.
//! - Layer boundaries come from the slicer's own markers when the file has them; otherwise from
//!   the Z at which material is extruded (travel lifts and z-hops never start a layer).
//! - Refusals (an `io::Error` of kind `InvalidData`, the stream ends): a line over 1 MiB, a
//!   layer of more than 4 million moves, and a G20 after printing began; every
//!   other input is read.

// The settings a file states about itself sit in their own stage, below this one, so that the
// estimator (which layers use) can read them too.
pub use crate::config;
pub mod dialect;

use std::collections::VecDeque;
use std::io::{self, BufRead};

use serde::Serialize;

pub use config::SlicerConfig;
pub use dialect::{MarkerKind, Role, Slicer, Tag};

use crate::gcode::{parse_line, strip_terminator, Command};
use crate::machine::{dist, Action, Diagnostics, Machine, Move};

/// Two Z values closer than this (mm) are the same layer.
const Z_EPS: f64 = 1e-4;
/// Arcs are linearized with chords no farther than this from the true arc (mm).
const ARC_TOLERANCE: f64 = 0.01;
/// While undecided whether a file has layer markers, at most this many inferred layers are
/// held back before settling on Z inference (markers, when present, come first).
const HOLD_LAYERS: usize = 3;
/// Layers held while a header promises markers that never come.
const HOLD_LAYERS_PROMISED: usize = 50;

/// One continuous extrusion: consecutive extruding moves with the same attributes.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Path {
    pub role: Role,
    /// Width in mm: from the slicer's comment when it gives one, else from E by the flow model.
    pub width: f64,
    /// Bead height in mm.
    pub height: f64,
    /// Z at which it is printed.
    pub z: f64,
    /// Index into [`LayerReader::objects`].
    pub object: Option<u32>,
    pub tool: u32,
    /// XY polyline; arcs are linearized.
    pub points: Vec<[f64; 2]>,
    /// Source line of each segment (`points.len() - 1` entries).
    pub seg_line: Vec<u64>,
    /// Filament (mm of E) of each segment.
    pub seg_e: Vec<f64>,
    /// Feedrate of the path's first move, mm/min.
    pub feed: f64,
}

/// Reusable buffers of an open path (see [`State::spare`]).
#[derive(Debug, Default)]
struct PathBuffers {
    points: Vec<[f64; 2]>,
    seg_line: Vec<u64>,
    seg_e: Vec<f64>,
}

impl Path {
    pub fn length(&self) -> f64 {
        self.points
            .windows(2)
            .map(|w| dist(w[0][0], w[0][1], w[1][0], w[1][1]))
            .sum()
    }

    pub fn e(&self) -> f64 {
        self.seg_e.iter().sum()
    }

    /// Width of the bead the path's E makes at its height (Slic3r flow model:
    /// cross-section = (w - h) h + pi (h/2)^2).
    pub fn e_width(&self, filament_area: f64) -> f64 {
        flow_width(self.e(), self.length(), self.height, filament_area)
    }
}

/// Bead width from extruded filament (mm), path length (mm), layer height (mm) and filament
/// cross-section (mm2), by the Slic3r flow model. Zero when undefined.
pub fn flow_width(e: f64, length: f64, height: f64, filament_area: f64) -> f64 {
    if length <= 1e-9 || height <= 1e-9 {
        return 0.0;
    }
    let area = e * filament_area / length;
    area / height + height * (1.0 - std::f64::consts::FRAC_PI_4)
}

/// Filament cross-section in mm2 for a diameter in mm.
pub fn filament_area(diameter: f64) -> f64 {
    std::f64::consts::PI * diameter * diameter / 4.0
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum LayerKind {
    /// Lines before the first layer (start G-code, priming).
    Preamble,
    Layer,
}

/// One layer (or the preamble) with its extrusions.
#[derive(Debug, Clone)]
pub struct Layer {
    pub kind: LayerKind,
    /// 0-based index among layers of kind [`LayerKind::Layer`].
    pub index: usize,
    /// The slicer's own layer number, where the marker carries one.
    pub marker_number: Option<i64>,
    pub z: f64,
    pub height: f64,
    /// Indices of the earlier layers this one is printed on, most recent first: usually the
    /// layer before it; several where objects of different layer heights interleave (see
    /// [`rests_on`]); empty for the first layer and the preamble.
    pub rests_on: Vec<usize>,
    /// The beads of the layer's own height rest on the layer before it alone, whatever its
    /// taller beads reach (infill printed every other layer at twice the height rests on
    /// the layer before that too; objects of another layer height interleaving do not count).
    pub walls_on_previous: bool,
    /// Earlier layers below those it rests on whose support material holds it across the
    /// slicer's support contact gap (see [`contact_under`]): only their support strands count
    /// under this layer. Empty without support material.
    pub contact: Vec<usize>,
    /// Earlier layers of any material whose top lies within [`CONTACT_GAP`] under this
    /// layer's bottom, below those it rests on (see [`gap_under`]): what the layer's support
    /// material stands on across the slicer's bottom contact gap (PrusaSlicer's
    /// `support_material_bottom_contact_distance`, Cura's `support_bottom_distance`). Only the
    /// layer's support strands stand on them. Empty on a layer without support material.
    pub gap_below: Vec<usize>,
    /// Z rises while the layer extrudes (a spiral vase's turn, a non-planar print): no layer
    /// below it at one height, nothing poa rewrites.
    pub helical: bool,
    /// How far this layer's beads squash out past their E-width (mm): the first layer's
    /// elephant foot, which PrusaSlicer's `elefant_foot_compensation` draws the outline in
    /// by so that the squashed layer ends on it; 0 on every other layer.
    pub spread: f64,
    pub paths: Vec<Path>,
    /// First and last source line (inclusive). An empty block has `last_line < first_line`.
    pub first_line: u64,
    pub last_line: u64,
    /// The exact bytes of the block's lines when `keep_raw` is on, else empty.
    pub raw: Vec<u8>,
    /// The interpreter's state before the block's first line, when `keep_raw` is on.
    pub start: Option<Box<Machine>>,
    /// All object names known so far (indexed by [`Path::object`]) when a name was added or
    /// changed while reading this block; `None` when unchanged.
    pub objects: Option<Vec<String>>,
}

/// Widest span (mm), in X or in Y, of one layer's extrusions that poa takes for a print: no
/// printer's bed is wider. Strands metres apart (a mistyped X 99999 on a tenth of the lines,
/// relative moves left on) are a damaged file, and they made the region search and the
/// deposition check, whose work grows with the area the strands span, take minutes and
/// gigabytes for a 200 kB file.
pub const MAX_LAYER_SPAN: f64 = 2000.0;

impl Layer {
    /// An error naming the farthest-out extrusion when the layer's extrusions span more than
    /// [`MAX_LAYER_SPAN`] in X or in Y.
    pub fn check_span(&self) -> io::Result<()> {
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for q in self.paths.iter().flat_map(|p| p.points.iter()) {
            for k in 0..2 {
                lo[k] = lo[k].min(q[k]);
                hi[k] = hi[k].max(q[k]);
            }
        }
        let Some(k) = (0..2).find(|&k| hi[k] - lo[k] > MAX_LAYER_SPAN) else {
            return Ok(());
        };
        // The point farthest from the layer's median on that axis: the damaged move.
        let mut values: Vec<f64> = self
            .paths
            .iter()
            .flat_map(|p| p.points.iter().map(move |q| q[k]))
            .collect();
        let mid = values.len() / 2;
        let median = *values.select_nth_unstable_by(mid, f64::total_cmp).1;
        let mut worst = (0.0, [0.0; 2], self.first_line);
        for p in &self.paths {
            for (i, q) in p.points.iter().enumerate() {
                let d = (q[k] - median).abs();
                if d > worst.0 {
                    let line = p.seg_line.get(i.saturating_sub(1)).copied();
                    worst = (d, *q, line.unwrap_or(self.first_line));
                }
            }
        }
        let (_, q, line) = worst;
        Err(io::Error::new(
            io::ErrorKind::InvalidData,
            format!(
                "line {line}: an extrusion to X{:.1} Y{:.1} spreads the layer at Z {:.2} over {:.0} mm, more than any printer's bed ({MAX_LAYER_SPAN:.0} mm): the file looks damaged (a mistyped number? G91 left on?); poa leaves it as it is",
                q[0],
                q[1],
                self.z,
                hi[k] - lo[k]
            ),
        ))
    }

    pub fn line_count(&self) -> u64 {
        (self.last_line + 1).saturating_sub(self.first_line)
    }

    /// Whether the layer is printed on the bed: the first layer, or a layer whose bottom
    /// (Z less its height) lies within half its height of the bed. Sequential printing
    /// (PrusaSlicer's complete objects) comes back down to the bed for each object, and the
    /// layer before that object's first is another object's top: nothing of it is over air.
    pub fn on_bed(&self) -> bool {
        self.kind == LayerKind::Layer
            && (self.index == 0
                || (self.height > 0.0 && self.z - self.height <= 0.5 * self.height + 1e-6))
    }

    /// Whether the layer is printed on the layer just before it in the file and on nothing
    /// else (every layer of a file with one layer height).
    pub fn on_previous(&self) -> bool {
        self.index > 0 && self.rests_on == [self.index - 1]
    }

    /// Whether the layer is printed on the layer just before it, perhaps through taller beads
    /// on older ones too (see [`Layer::walls_on_previous`]).
    pub fn over_previous(&self) -> bool {
        self.on_previous() || self.walls_on_previous
    }
}

/// Tallest layer or bead height a comment may state (mm): beyond it the comment is ignored.
const MAX_HEIGHT: f64 = 10.0;

/// Earlier layers looked through for what a layer rests on.
pub const RECENT_LAYERS: usize = 32;

/// The layers a layer with top `z` and bead height `height` is printed on, given the
/// `recent` layers before it (index, top Z; oldest first), most recent first.
///
/// Walking back through the file, a layer whose top lies between this layer's bottom and its
/// top is under it; one at the same top is another object's part of the same layer (skipped);
/// one above its top, or below its bottom, ends the walk (the first is sequential printing
/// coming back down, the second a layer under the layer below). Objects sliced at different
/// layer heights interleave: PrusaSlicer's layer at Z 0.4 of a 0.2 mm object comes after the
/// 0.35 mm layer of a 0.15 mm object, and rests on both it and the layer at 0.2. With one
/// layer height the walk finds exactly the layer before; when it finds nothing (a gap), the
/// layer before is taken all the same.
pub fn rests_on(recent: &VecDeque<(usize, f64)>, z: f64, height: f64) -> Vec<usize> {
    // Slicers print Z to a micrometre or so; a layer step is 50 micrometres or more.
    let eps = (0.25 * height).clamp(0.002, 0.02);
    let bottom = z - height;
    let mut on = Vec::new();
    for &(i, top) in recent.iter().rev() {
        if (top - z).abs() <= eps {
            continue;
        }
        if top > z || top < bottom - eps {
            break;
        }
        on.push(i);
    }
    if on.is_empty() {
        on.extend(recent.back().map(|&(i, _)| i));
    }
    on
}

/// Deepest gap (mm) between a layer's bottom and the top of support material under it that
/// still holds it: slicers leave a contact gap over support and raft so that the part comes
/// off (PrusaSlicer's `support_material_contact_distance` and `raft_contact_distance`, 0.1-0.3
/// mm in the shipped profiles; Cura's `support_top_distance`, one layer by default).
pub const CONTACT_GAP: f64 = 0.4;

/// The layers under a layer with top `z` and bead height `height` whose support material
/// holds it across the contact gap: walking back through `recent` (as [`rests_on`]), the
/// layers with support material whose top lies below the layer's bottom by at most
/// [`CONTACT_GAP`] (or at its bottom, where [`rests_on`] did not find them), most recent
/// first. `support(i)` says whether layer `i` prints support
/// material (`Some`) and whether nothing else (`Some(true)`). A part's first layer over a
/// raft, or over support that starts lower, rests on layers of support alone: the walk goes
/// down through them all (the raft's top is further down than the gap). The walk ends at a
/// layer more than a layer height above the layer's top (sequential printing coming back
/// down) or deeper than the gap.
pub fn contact_under(
    recent: &VecDeque<(usize, f64)>,
    support: impl Fn(usize) -> Option<bool>,
    rests: &[usize],
    z: f64,
    height: f64,
) -> Vec<usize> {
    let mut through = !rests.is_empty() && rests.iter().all(|&i| support(i) == Some(true));
    let mut under = Vec::new();
    walk_under(recent, rests, z, height, |i, deep| {
        let s = support(i);
        through &= s == Some(true);
        if !through && deep {
            return false;
        }
        if s.is_some() {
            under.push(i);
        }
        true
    });
    under
}

/// Walks back through `recent` from under a layer with top `z` and bead height `height`,
/// past the layers it rests on (`rests`) and those at its own height (another object's part
/// of the same layer, or Cura's first layer over a raft, printed higher than the layer after
/// it), calling `visit(layer, deeper than the contact gap)` until it returns false. The walk
/// ends at a layer more than a layer height above the layer's top (sequential printing
/// coming back down).
fn walk_under(
    recent: &VecDeque<(usize, f64)>,
    rests: &[usize],
    z: f64,
    height: f64,
    mut visit: impl FnMut(usize, bool) -> bool,
) {
    let eps = (0.25 * height).clamp(0.002, 0.02);
    let bottom = z - height;
    for &(i, top) in recent.iter().rev() {
        if rests.contains(&i) {
            continue;
        }
        if top > z + height {
            break;
        }
        if top > z - eps {
            continue;
        }
        if !visit(i, top < bottom - CONTACT_GAP - eps) {
            break;
        }
    }
}

/// Most layers [`gap_under`] gives: the nearest ones hold the support (the others lie
/// under them).
const GAP_LAYERS: usize = 2;

/// The layers under a layer with top `z` and bead height `height` whose material the layer's
/// support stands on across the slicer's bottom contact gap: walking back through `recent`
/// (as [`contact_under`]), past those it rests on (`rests`), the layers whose top lies below
/// the layer's bottom by at most [`CONTACT_GAP`], nearest first, [`GAP_LAYERS`] at most.
pub fn gap_under(
    recent: &VecDeque<(usize, f64)>,
    rests: &[usize],
    z: f64,
    height: f64,
) -> Vec<usize> {
    let mut under = Vec::new();
    walk_under(recent, rests, z, height, |i, deep| {
        if deep || under.len() == GAP_LAYERS {
            return false;
        }
        under.push(i);
        true
    });
    under
}

/// The bead height that carries the most of the layer's extrusion length (0 when no path
/// states one).
pub fn bead_height<'a>(paths: impl IntoIterator<Item = &'a Path>) -> f64 {
    let mut by_height: Vec<(f64, f64)> = Vec::new();
    for p in paths
        .into_iter()
        .filter(|p| p.height > 0.0 && p.height <= MAX_HEIGHT)
    {
        let len = p.length();
        match by_height
            .iter_mut()
            .find(|(h, _)| (h - p.height).abs() < 1e-3)
        {
            Some(e) => e.1 += len,
            None => by_height.push((p.height, len)),
        }
    }
    by_height
        .iter()
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .map_or(0.0, |e| e.0)
}

/// How layer boundaries are found.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum LayerSource {
    /// Not settled yet.
    Undecided,
    /// The slicer's layer markers.
    Markers,
    /// The Z of extrusion moves.
    InferredFromZ,
}

/// Options for [`LayerReader`].
#[derive(Debug, Clone, Default)]
pub struct ReaderOptions {
    /// Keep each layer's raw bytes (needed to rewrite; not for analysis).
    pub keep_raw: bool,
    pub config: SlicerConfig,
}

#[derive(Debug)]
struct Builder {
    kind: LayerKind,
    marker_number: Option<i64>,
    z_tag: Option<f64>,
    height_tag: Option<f64>,
    extrusion_z: Option<f64>,
    helical: bool,
    first_line: u64,
    last_line: u64,
    raw: Vec<u8>,
    paths: Vec<Path>,
    start: Option<Box<Machine>>,
    /// XY length (mm) of the block's moves that push filament, and of those outside a tagged
    /// wipe that pull it back.
    e_forward: f64,
    e_back: f64,
}

impl Builder {
    fn new(kind: LayerKind, first_line: u64) -> Self {
        Builder {
            kind,
            marker_number: None,
            z_tag: None,
            height_tag: None,
            extrusion_z: None,
            helical: false,
            first_line,
            last_line: first_line.wrapping_sub(1),
            raw: Vec::new(),
            paths: Vec::new(),
            start: None,
            e_forward: 0.0,
            e_back: 0.0,
        }
    }
}

/// Facts about the whole file gathered while reading.
#[derive(Debug, Clone, Serialize)]
pub struct FileFacts {
    pub slicer: Slicer,
    pub slicer_version: String,
    pub layer_source: LayerSource,
    pub spiral_vase: bool,
    /// `; filament used [mm] = ...` (or Cura's `;Filament used: ...m`) as the slicer stated it.
    pub stated_filament_mm: Option<f64>,
    pub lines: u64,
    pub bytes: u64,
}

/// Streams [`Layer`]s out of G-code.
pub struct LayerReader<R> {
    input: R,
    /// A line split across two reads of the input buffer.
    partial: Vec<u8>,
    next_line: u64,
    done: bool,
    st: State,
}

/// Everything the reader knows between two lines.
struct State {
    machine: Machine,
    /// Print-time estimate over every line, when asked for.
    estimator: Option<crate::estimate::Estimator>,
    keep_raw: bool,
    filament_area: f64,
    config_layer_height: Option<f64>,
    /// [`Layer::spread`] of the first layer.
    first_layer_spread: f64,
    facts: FileFacts,
    objects: Vec<String>,
    /// What identifies each object in the file (label text, M486 id).
    object_keys: Vec<String>,
    objects_changed: bool,
    diagnostics: Diagnostics,
    marker_kind: Option<MarkerKind>,
    markers_promised: bool,
    role_tag: Option<Role>,
    cura_bridge: bool,
    width_tag: Option<f64>,
    height_tag: Option<f64>,
    object: Option<u32>,
    in_config: bool,
    cur: Builder,
    open_path: Option<Path>,
    /// The open path's buffers, kept between paths: a path grows in them and is copied out
    /// at its exact size when it closes (growing each path's own vectors from one point
    /// reallocated them a dozen times: an eighth of the reader's time on a plate).
    spare: PathBuffers,
    /// (raw offset, line, interpreter state before it) of the first Z change since the last
    /// extrusion.
    z_change: Option<(usize, u64, Option<Box<Machine>>)>,
    held: Vec<Layer>,
    /// Moves of the layer being read, and the line where one past [`MAX_LAYER_MOVES`] came.
    layer_moves: usize,
    too_many_moves: Option<u64>,
    /// Whether anything was extruded yet, and the line of a G20 that came after.
    printed: bool,
    inches_mid_print: Option<u64>,
    /// Inside a wipe the slicer tagged (`;WIPE_START` .. `;WIPE_END`), and whether one was.
    in_wipe: bool,
    wipes_tagged: bool,
    /// The first line of a layer, after printing began, whose moves pull filament back
    /// outside wipes ([`E_BACK_SHARE`]), and the share.
    e_backwards: Option<(u64, f64)>,
    ready: VecDeque<Layer>,
    next_index: usize,
    prev_layer_z: f64,
    last_height: f64,
    /// The last [`RECENT_LAYERS`] layers' (index, top Z), for [`rests_on`].
    recent: VecDeque<(usize, f64)>,
    /// The layers among [`Self::recent`] that print support material (index, and whether
    /// nothing else).
    recent_support: Vec<(usize, bool)>,
    /// The interpreter's state before the line being handled (kept only with `keep_raw`).
    before_line: Machine,
    /// The nozzle diameter, where the file states no filament diameter (E is then read as
    /// 1.75 mm filament): the external perimeters' widths are sampled against it.
    unstated_filament: Option<f64>,
    wall_samples: Vec<f64>,
}

impl<R: BufRead> LayerReader<R> {
    pub fn new(input: R, options: ReaderOptions) -> Self {
        LayerReader {
            input,
            partial: Vec::new(),
            next_line: 1,
            done: false,
            st: State::new(options),
        }
    }

    pub fn facts(&self) -> &FileFacts {
        &self.st.facts
    }

    /// Also estimates the print time of every line read, with these limits.
    pub fn with_estimate(mut self, limits: crate::estimate::Limits) -> Self {
        self.st.estimator = Some(crate::estimate::Estimator::new(limits));
        self
    }

    /// The print time of what was read so far (s), when [`LayerReader::with_estimate`] asked
    /// for it.
    pub fn estimated_time(&self) -> Option<f64> {
        self.st.estimator.clone().map(|e| e.finish().0)
    }

    pub fn machine(&self) -> &Machine {
        &self.st.machine
    }

    /// Reader diagnostics merged with the interpreter's.
    pub fn diagnostics(&self) -> Diagnostics {
        let mut d = self.st.diagnostics.clone();
        d.merge(&self.st.machine.diagnostics);
        d
    }

    pub fn filament_area(&self) -> f64 {
        self.st.filament_area
    }

    /// Object names, indexed by [`Path::object`].
    pub fn objects(&self) -> &[String] {
        &self.st.objects
    }

    /// Feeds every complete line in the input's buffer to the state; returns false at the end
    /// of input. Lines are handed over straight from the buffer, without a copy, unless one
    /// straddles two reads.
    fn pump(&mut self) -> io::Result<bool> {
        let buf = loop {
            match self.input.fill_buf() {
                Ok(b) => break b,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => return Err(e),
            }
        };
        if buf.is_empty() {
            if !self.partial.is_empty() {
                let line = std::mem::take(&mut self.partial);
                self.st.handle_line(&line, self.next_line);
                self.next_line += 1;
            }
            return Ok(false);
        }
        let mut used = 0;
        if !self.partial.is_empty() {
            match memchr::memchr(b'\n', buf) {
                Some(i) => {
                    self.partial.extend_from_slice(&buf[..=i]);
                    used = i + 1;
                    let line = std::mem::take(&mut self.partial);
                    self.st.handle_line(&line, self.next_line);
                    self.next_line += 1;
                    self.partial = line;
                    self.partial.clear();
                }
                None => {
                    self.partial.extend_from_slice(buf);
                    let n = buf.len();
                    self.input.consume(n);
                    if self.partial.len() > crate::gcode::MAX_LINE {
                        return Err(crate::gcode::line_too_long(self.next_line));
                    }
                    return Ok(true);
                }
            }
        }
        while let Some(i) = memchr::memchr(b'\n', &buf[used..]) {
            self.st
                .handle_line(&buf[used..used + i + 1], self.next_line);
            self.next_line += 1;
            used += i + 1;
        }
        self.partial.extend_from_slice(&buf[used..]);
        let n = buf.len();
        self.input.consume(n);
        if let Some(line) = self.st.inches_mid_print {
            return Err(io::Error::new(
                io::ErrorKind::InvalidData,
                format!(
                    "line {line}: G20 (inches) after printing began would print the rest 25.4 times larger; the file is damaged: slice it again"
                ),
            ));
        }
        if let Some((line, share)) = self.st.e_backwards {
            return Err(io::Error::new(
                io::ErrorKind::InvalidData,
                format!(
                    "line {line}: this layer's printing moves pull filament back on {:.0} % of their length: its E values do not fit the E mode in force (an M82 or M83 added or lost mid-print); the file is damaged: slice it again",
                    100.0 * share
                ),
            ));
        }
        if let Some(line) = self.st.too_many_moves {
            return Err(io::Error::new(
                io::ErrorKind::InvalidData,
                format!(
                    "line {line}: one layer holds more than {MAX_LAYER_MOVES} moves, which no slicer writes; the file is damaged or not a print"
                ),
            ));
        }
        Ok(true)
    }
}

/// Share of a layer's moves with E (by XY length) that may pull filament back outside the
/// wipes a slicer tags. PrusaSlicer and SuperSlicer pull back while moving only in tagged
/// wipes (judged once a wipe was tagged), Cura never: 0 % in 626 held-out files by both.
/// OrcaSlicer, Bambu Studio and Creality Print come from PrusaSlicer's code and tag their
/// wipes the same way (`;WIPE_START`, Bambu `; WIPE_START`): judged once a wipe was tagged,
/// as PrusaSlicer is (none of 21 Orca and Bambu files refused, among them a real Bambu Studio
/// print of 137 layers with a prime tower and 125 tool changes). A relative-E file read as absolute
/// (an M82 slipped in mid-print) pulls back on 40-65 % of each layer's moves, and its layers,
/// printed in fragments, left every layer above full of false regions (9 mushrooms: 1 738
/// regions, 22 s and 188 MB). Judged only for those slicers: others wipe untagged, and a
/// plate of pins wiped after each 2.5 mm loop pulls back on more than half its moves.
const E_BACK_SHARE: f64 = 0.2;
/// Fewest mm of moves with E a layer is judged on.
const E_BACK_MIN_MM: f64 = 50.0;

/// Most moves (arcs counted by the chords they are read as) one layer may hold: some 400
/// times a busy layer of a real plate (a 16-part plate averages 4 500), and what keeps a
/// layer's model and its deposition check within a few hundred megabytes.
const MAX_LAYER_MOVES: usize = 4_000_000;

impl State {
    fn new(options: ReaderOptions) -> Self {
        let cfg = &options.config;
        let mut machine = Machine::new();
        // A file that never says M82/M83 follows its slicer's setting.
        if cfg.relative_e() == Some(true) {
            let p = parse_line(b"M83");
            machine.step(&p, 0);
            machine.e_modes.relative = false;
        }
        // Binary G-code names its producer in metadata, not in a comment.
        let producer = cfg
            .get("Producer")
            .and_then(|p| dialect::detect(&format!("generated by {p}")));
        State {
            machine: machine.clone(),
            estimator: None,
            keep_raw: options.keep_raw,
            filament_area: cfg.e_area(),
            unstated_filament: cfg
                .filament_diameter_unstated()
                .then(|| cfg.nozzle_diameter()),
            wall_samples: Vec::new(),
            config_layer_height: cfg.layer_height(),
            first_layer_spread: cfg.elephant_foot(),
            markers_promised: producer
                .as_ref()
                .is_some_and(|p| p.0.writes_layer_markers()),
            facts: FileFacts {
                slicer: producer.as_ref().map_or(Slicer::Unknown, |p| p.0),
                slicer_version: producer.map(|p| p.1).unwrap_or_default(),
                layer_source: LayerSource::Undecided,
                spiral_vase: false,
                stated_filament_mm: None,
                lines: 0,
                bytes: 0,
            },
            objects: Vec::new(),
            object_keys: Vec::new(),
            objects_changed: false,
            diagnostics: {
                let mut d = Diagnostics::default();
                if let Some((_, why)) = cfg
                    .inferred()
                    .iter()
                    .find(|(k, _)| k == "filament_diameter")
                {
                    d.add("filament-diameter", 1, || why.clone());
                }
                d
            },
            marker_kind: None,
            role_tag: None,
            cura_bridge: false,
            width_tag: None,
            height_tag: None,
            object: None,
            in_config: false,
            cur: Builder {
                start: options.keep_raw.then(|| Box::new(machine.snapshot())),
                ..Builder::new(LayerKind::Preamble, 1)
            },
            open_path: None,
            spare: PathBuffers::default(),
            z_change: None,
            held: Vec::new(),
            layer_moves: 0,
            too_many_moves: None,
            printed: false,
            inches_mid_print: None,
            in_wipe: false,
            wipes_tagged: false,
            e_backwards: None,
            ready: VecDeque::new(),
            next_index: 0,
            prev_layer_z: 0.0,
            last_height: 0.0,
            recent: VecDeque::new(),
            recent_support: Vec::new(),
            before_line: Machine::new(),
        }
    }

    /// A new block starting at `line`, remembering the interpreter's state there (the machine
    /// has not run `line` yet when this is called).
    fn new_builder(&self, kind: LayerKind, line: u64) -> Builder {
        let mut b = Builder::new(kind, line);
        if self.keep_raw {
            b.start = Some(Box::new(self.machine.snapshot()));
        }
        b
    }

    fn handle_line(&mut self, raw: &[u8], number: u64) {
        if self.keep_raw {
            self.before_line.copy_state_from(&self.machine);
        }
        let content = strip_terminator(raw);
        let parsed = parse_line(content);

        if let Some(comment) = parsed.comment {
            self.handle_comment(comment, number, matches!(parsed.command, Command::Empty));
        }

        match parsed.command {
            Command::Extended { name, params } => self.handle_extended(name, params),
            Command::Code {
                letter: b'M',
                number: 486.0,
            } => self.handle_m486(&parsed, content),
            Command::Unknown(text) if text.starts_with(b"M486") => {
                self.handle_m486(&parsed, content)
            }
            // A move with a word that is no number (`G1 XNaN Y20 E1`) is not read, E and all:
            // say so, as for a number out of range.
            Command::Unknown(text) if crate::gcode::is_move_word(text) => {
                let shown = String::from_utf8_lossy(&text[..text.len().min(60)]).into_owned();
                self.diagnostics.add("bad-move", number, || {
                    format!("`{shown}` has a word that is no number; the move was ignored")
                });
            }
            _ => {}
        }

        if self.printed
            && !self.machine.inches()
            && self.inches_mid_print.is_none()
            && matches!(parsed.command, Command::Code { letter: b'G', number } if number == 20.0)
        {
            self.inches_mid_print = Some(number);
        }
        let action = self.machine.step(&parsed, number);
        if let Some(e) = &mut self.estimator {
            e.line(&parsed, &action);
        }
        if let Action::Move(m) = &action {
            if m.e != 0.0 && m.from != m.to {
                if m.e > 0.0 {
                    self.cur.e_forward += m.xy_length();
                } else if !self.in_wipe {
                    self.cur.e_back += m.xy_length();
                }
            }
        }
        match action {
            Action::Move(m) => self.handle_move(&m, number),
            Action::FirmwareRetract | Action::FirmwareUnretract | Action::Tool(_) => {
                self.close_path()
            }
            _ => {}
        }

        if self.keep_raw {
            self.cur.raw.extend_from_slice(raw);
        }
        self.cur.last_line = number;
        self.facts.lines = number;
        self.facts.bytes += raw.len() as u64;
    }

    fn handle_comment(&mut self, comment: &[u8], number: u64, whole_line: bool) {
        let text = String::from_utf8_lossy(comment);
        if self.in_config {
            if matches!(dialect::parse_tag(&text), Some(Tag::ConfigEnd)) {
                self.in_config = false;
            }
            return;
        }
        if whole_line && self.facts.slicer == Slicer::Unknown && number <= 400 {
            if let Some((slicer, version)) = dialect::detect(&text) {
                self.facts.slicer = slicer;
                self.facts.slicer_version = version;
                self.markers_promised = slicer.writes_layer_markers();
                let said = self.machine.e_modes.relative || self.machine.e_modes.absolute;
                if slicer.relative_e_unsaid() && !said {
                    // Until the file says otherwise, E is per move.
                    self.machine.step(&parse_line(b"M83"), 0);
                    self.machine.e_modes.relative = false;
                }
                return;
            }
        }
        let Some(tag) = dialect::parse_tag(&text) else {
            if !whole_line && self.facts.slicer == Slicer::Slic3r {
                // Slic3r 1.3 only says what a move is in a trailing comment.
                if let Some(role) = Role::from_slicer_name(&text) {
                    self.set_role(Some(role));
                }
            }
            if whole_line {
                self.stated_filament(&text);
            }
            return;
        };
        match tag {
            Tag::LayerChange {
                kind,
                number: n,
                z,
                height,
            } => {
                self.marker(kind, n, z, number);
                if let Some(h) = height
                    .filter(|h| *h <= MAX_HEIGHT)
                    .filter(|_| self.marker_kind == Some(kind))
                {
                    self.cur.height_tag = Some(h);
                    self.height_tag = Some(h);
                }
            }
            Tag::Z(z) => {
                if self.cur.kind == LayerKind::Layer && self.cur.z_tag.is_none() {
                    self.cur.z_tag = Some(z);
                }
            }
            Tag::Height(h) => {
                if h > 0.0 && h <= MAX_HEIGHT {
                    if self.cur.kind == LayerKind::Layer && self.cur.height_tag.is_none() {
                        self.cur.height_tag = Some(h);
                    }
                    self.height_tag = Some(h);
                }
            }
            Tag::Role(role, _) => {
                self.cura_bridge = false;
                self.set_role(Some(role.unwrap_or(Role::Unknown)));
            }
            Tag::CuraBridge => {
                self.cura_bridge = true;
                self.close_path();
            }
            Tag::Width(w) => {
                if w > 0.0 && w < 50.0 {
                    self.width_tag = Some(w);
                }
            }
            Tag::Tool { height, width } => {
                if width > 0.0 && width < 50.0 {
                    self.width_tag = Some(width);
                }
                if height > 0.0 && height <= MAX_HEIGHT {
                    self.height_tag = Some(height);
                }
            }
            Tag::ObjectStart(name) => self.start_object(name.clone(), name),
            Tag::ObjectEnd => self.set_object(None),
            Tag::ConfigBegin => self.in_config = true,
            Tag::WipeStart => {
                self.in_wipe = true;
                self.wipes_tagged = true;
            }
            Tag::WipeEnd => self.in_wipe = false,
            Tag::ConfigEnd => {}
        }
    }

    fn stated_filament(&mut self, text: &str) {
        let t = text.trim();
        if let Some(v) = t.strip_prefix("filament used [mm] =") {
            self.facts.stated_filament_mm = v
                .split(',')
                .map(|x| x.trim().parse::<f64>().ok())
                .sum::<Option<f64>>()
                .or(self.facts.stated_filament_mm);
        } else if let Some(v) = t.strip_prefix("Filament used:") {
            // Cura: metres, per extruder.
            self.facts.stated_filament_mm = v
                .split(',')
                .map(|x| x.trim().trim_end_matches('m').parse::<f64>().ok())
                .sum::<Option<f64>>()
                .map(|m| m * 1000.0)
                // CuraEngine run on its own writes `0m`, a placeholder its front end fills in.
                .filter(|mm| *mm > 0.0);
        }
    }

    fn set_role(&mut self, role: Option<Role>) {
        if role != self.role_tag {
            self.close_path();
            self.role_tag = role;
        }
    }

    /// Selects the object known by `key`, registering it under `name` the first time.
    fn start_object(&mut self, key: String, name: String) {
        let idx = match self.object_keys.iter().position(|o| *o == key) {
            Some(i) => i,
            None => {
                self.object_keys.push(key);
                self.objects.push(name);
                self.objects_changed = true;
                self.objects.len() - 1
            }
        };
        self.set_object(Some(idx as u32));
    }

    fn set_object(&mut self, object: Option<u32>) {
        if object != self.object {
            self.close_path();
            self.object = object;
        }
    }

    fn handle_extended(&mut self, name: &[u8], params: &[u8]) {
        let object_name = || {
            let p = String::from_utf8_lossy(params);
            p.split_whitespace().find_map(|kv| {
                kv.strip_prefix("NAME=")
                    .map(|s| s.trim_matches('"').to_string())
            })
        };
        match name {
            b"EXCLUDE_OBJECT_START" => {
                if let Some(n) = object_name() {
                    self.start_object(n.clone(), n);
                }
            }
            b"EXCLUDE_OBJECT_END" => self.set_object(None),
            _ => {}
        }
    }

    fn handle_m486(&mut self, parsed: &crate::gcode::Parsed<'_>, content: &[u8]) {
        if let Some(s) = parsed.get(b'S') {
            if s < 0.0 {
                self.set_object(None);
            } else {
                let id = s as i64;
                self.start_object(format!("M486 {id}"), format!("id {id}"));
            }
        } else if let Some(pos) = content.windows(2).position(|w| w == b" A") {
            // `M486 A<name>` names the object selected by the last `M486 S`.
            let name = String::from_utf8_lossy(&content[pos + 2..])
                .trim()
                .to_string();
            if let Some(i) = self.object {
                if let Some(id) = self.object_keys[i as usize].strip_prefix("M486 ") {
                    self.objects[i as usize] = format!("{name} (id {id})");
                    self.objects_changed = true;
                }
            }
        }
    }

    fn marker(&mut self, kind: MarkerKind, n: Option<i64>, z: Option<f64>, line: u64) {
        match (self.facts.layer_source, self.marker_kind) {
            (LayerSource::Markers, Some(k)) if k != kind => return,
            (LayerSource::InferredFromZ, _) => {
                self.diagnostics.add("late-marker", line, || {
                    "layer marker after layers were inferred from Z; ignored".to_string()
                });
                return;
            }
            (LayerSource::Undecided, _) => {
                // Everything inferred so far came before the first marker: it is preamble.
                self.facts.layer_source = LayerSource::Markers;
                self.marker_kind = Some(kind);
                self.cur.kind = LayerKind::Preamble;
                self.close_path();
                let next = self.new_builder(LayerKind::Layer, line);
                let cur = std::mem::replace(&mut self.cur, next);
                let last = self.complete(cur);
                let mut blocks = self.held.drain(..).chain(std::iter::once(last));
                if let Some(mut pre) = blocks.next() {
                    for l in blocks {
                        pre.raw.extend_from_slice(&l.raw);
                        pre.paths.extend(l.paths);
                        pre.last_line = l.last_line;
                    }
                    pre.kind = LayerKind::Preamble;
                    pre.index = 0;
                    pre.marker_number = None;
                    pre.height = 0.0;
                    pre.z = 0.0;
                    for p in &mut pre.paths {
                        if p.role == Role::Unknown {
                            p.role = Role::WipePrime;
                        }
                    }
                    self.ready.push_back(pre);
                }
                self.next_index = 0;
                self.prev_layer_z = 0.0;
                self.last_height = 0.0;
                self.recent.clear();
                self.recent_support.clear();
            }
            _ => self.finish_current(line),
        }
        self.cur.kind = LayerKind::Layer;
        self.cur.marker_number = n;
        self.cur.z_tag = z;
    }

    fn handle_move(&mut self, m: &Move, line: u64) {
        if !m.is_extrusion() {
            let moved = m.from != m.to;
            if moved || m.e != 0.0 {
                self.close_path();
            }
            if (m.to[2] - m.from[2]).abs() > 1e-9 && self.z_change.is_none() {
                let before = self.keep_raw.then(|| Box::new(self.before_line.clone()));
                self.z_change = Some((self.cur.raw.len(), line, before));
            }
            return;
        }
        self.printed = true;
        let z = m.to[2];
        let spiral = (m.to[2] - m.from[2]).abs() > 1e-9;
        if spiral && !self.facts.spiral_vase {
            self.facts.spiral_vase = true;
            self.diagnostics.add("spiral", line, || {
                "Z rises while extruding: spiral vase (or a non-planar) print".to_string()
            });
        }
        if self.facts.layer_source != LayerSource::Markers {
            self.infer_layer(z, spiral, line);
        }
        if self.cur.extrusion_z.is_none() {
            self.cur.extrusion_z = Some(z);
        }
        self.cur.helical |= spiral;
        self.z_change = None;
        self.extend_path(m, line);
    }

    /// Z inference: a new layer starts where the first Z change after the previous
    /// extrusion happened, when material is laid at a different Z.
    fn infer_layer(&mut self, z: f64, spiral: bool, line: u64) {
        let new_layer = match (self.cur.kind, self.cur.extrusion_z) {
            (LayerKind::Preamble, _) | (_, None) => true,
            (LayerKind::Layer, Some(lz)) => {
                if spiral {
                    let step = if self.last_height > 0.0 {
                        self.last_height
                    } else {
                        self.config_layer_height.unwrap_or(0.2)
                    };
                    z - lz >= step * 0.999 || z < lz - Z_EPS
                } else {
                    (z - lz).abs() > Z_EPS
                }
            }
        };
        if !new_layer {
            return;
        }
        if self.cur.kind == LayerKind::Layer && self.cur.extrusion_z.is_none() {
            // A layer with no extrusion yet (only a Z move): keep filling it.
            return;
        }
        self.close_path();
        let (offset, first_line, start) = self.z_change.take().unwrap_or_else(|| {
            (
                self.cur.raw.len(),
                line,
                self.keep_raw.then(|| Box::new(self.before_line.clone())),
            )
        });
        let tail = if self.keep_raw {
            self.cur.raw.split_off(offset.min(self.cur.raw.len()))
        } else {
            Vec::new()
        };
        let old_last = self.cur.last_line;
        self.cur.last_line = first_line.saturating_sub(1);
        self.finish_current(first_line);
        self.cur.kind = LayerKind::Layer;
        self.cur.raw = tail;
        self.cur.last_line = old_last;
        self.cur.start = start;
    }

    fn extend_path(&mut self, m: &Move, line: u64) {
        // Cura's `;BRIDGE` marks the current feature as printed with bridge settings: a
        // bridged wall is still the part's outline (an overhang perimeter, as PrusaSlicer tags
        // it), bridged skin is bridge infill.
        let role = if self.cura_bridge {
            match self.role_tag {
                Some(Role::ExternalPerimeter | Role::Perimeter | Role::OverhangPerimeter) => {
                    Role::OverhangPerimeter
                }
                _ => Role::BridgeInfill,
            }
        } else {
            match (self.role_tag, self.cur.kind) {
                (Some(r), _) => r,
                (None, LayerKind::Preamble) => Role::WipePrime,
                (None, LayerKind::Layer) => Role::Unknown,
            }
        };
        let width = self.width_tag.unwrap_or(0.0);
        let height = self.height_tag.unwrap_or(0.0);
        let start = [m.from[0], m.from[1]];
        if let Some(p) = &self.open_path {
            let last = p.points[p.points.len() - 1];
            let same = p.role == role
                && p.width == width
                && p.height == height
                && p.object == self.object
                && p.tool == self.machine.tool
                && (last[0] - start[0]).abs() < 1e-6
                && (last[1] - start[1]).abs() < 1e-6
                && (p.z - m.to[2]).abs() < Z_EPS;
            if !same {
                self.close_path();
            }
        }
        let spare = &mut self.spare;
        let path = self.open_path.get_or_insert_with(|| {
            let mut points = std::mem::take(&mut spare.points);
            points.push(start);
            Path {
                role,
                width,
                height,
                z: m.to[2],
                object: self.object,
                tool: self.machine.tool,
                points,
                seg_line: std::mem::take(&mut spare.seg_line),
                seg_e: std::mem::take(&mut spare.seg_e),
                feed: m.feed,
            }
        });
        if m.arc.is_none() {
            path.points.push([m.to[0], m.to[1]]);
            path.seg_line.push(line);
            path.seg_e.push(m.e);
            self.layer_moves += 1;
            if self.layer_moves > MAX_LAYER_MOVES && self.too_many_moves.is_none() {
                self.too_many_moves = Some(line);
            }
            return;
        }
        let pts = m.points(ARC_TOLERANCE);
        self.layer_moves += pts.len();
        if self.layer_moves > MAX_LAYER_MOVES && self.too_many_moves.is_none() {
            self.too_many_moves = Some(line);
        }
        let total_len = m.xy_length();
        let mut prev = pts[0];
        for p in &pts[1..] {
            let seg = dist(prev[0], prev[1], p[0], p[1]);
            let e = if total_len > 0.0 {
                m.e * seg / total_len
            } else {
                0.0
            };
            path.points.push(*p);
            path.seg_line.push(line);
            path.seg_e.push(e);
            prev = *p;
        }
    }

    fn close_path(&mut self) {
        if let Some(mut p) = self.open_path.take() {
            let exact = Path {
                points: p.points.as_slice().to_vec(),
                seg_line: p.seg_line.as_slice().to_vec(),
                seg_e: p.seg_e.as_slice().to_vec(),
                ..p
            };
            p.points.clear();
            p.seg_line.clear();
            p.seg_e.clear();
            self.spare = PathBuffers {
                points: p.points,
                seg_line: p.seg_line,
                seg_e: p.seg_e,
            };
            self.cur.paths.push(exact);
        }
    }

    /// Ends the current block and starts a new, empty one at `next_first_line`.
    fn finish_current(&mut self, next_first_line: u64) {
        self.close_path();
        self.layer_moves = 0;
        let kind = self.cur.kind;
        let mut next = self.new_builder(kind, next_first_line);
        // Consecutive layers are alike in size: one allocation instead of a doubling series
        // of copies of a megabyte-sized buffer.
        if self.keep_raw {
            next.raw
                .reserve(self.cur.raw.len() + self.cur.raw.len() / 8);
        }
        next.paths.reserve(self.cur.paths.len());
        let b = std::mem::replace(&mut self.cur, next);
        let layer = self.complete(b);
        match self.facts.layer_source {
            LayerSource::Undecided => {
                let is_layer = layer.kind == LayerKind::Layer;
                self.held.push(layer);
                if !is_layer {
                    return;
                }
                let limit = if self.markers_promised {
                    HOLD_LAYERS_PROMISED
                } else {
                    HOLD_LAYERS
                };
                if self.held.len() > limit {
                    self.settle_inferred();
                }
            }
            _ => self.ready.push_back(layer),
        }
    }

    fn settle_inferred(&mut self) {
        if self.markers_promised {
            self.diagnostics.add("no-markers", self.facts.lines, || {
                format!(
                    "{} header but no layer markers: layers inferred from Z",
                    self.facts.slicer.name()
                )
            });
        } else {
            self.diagnostics.add("no-markers", self.facts.lines, || {
                "no layer comments: layers inferred from Z".to_string()
            });
        }
        self.facts.layer_source = LayerSource::InferredFromZ;
        self.ready.extend(self.held.drain(..));
    }

    /// Samples the external perimeters' widths (layers above the first) where the file
    /// states no filament diameter, and notes once when they read as beads far narrower
    /// than the nozzle makes: the file's E is most likely in 2.85 mm filament (Lulzbot,
    /// older Ultimakers), and poa's loops would come out 2.65 times too heavy.
    fn sample_walls(&mut self, paths: &[Path], line: u64) {
        const SAMPLES: usize = 64;
        let Some(nozzle) = self.unstated_filament else {
            return;
        };
        if self.wall_samples.len() >= SAMPLES {
            return;
        }
        self.wall_samples.extend(
            paths
                .iter()
                .filter(|p| p.role == Role::ExternalPerimeter && p.length() > 1.0)
                .map(|p| p.width)
                .filter(|w| w.is_finite())
                .take(SAMPLES - self.wall_samples.len()),
        );
        if self.wall_samples.len() < SAMPLES {
            return;
        }
        let mut w = self.wall_samples.clone();
        w.sort_by(f64::total_cmp);
        let median = w[w.len() / 2];
        // 2.85 mm filament read as 1.75 gives a 2.65 times smaller cross-section: walls
        // about 0.4 of the nozzle wide, where slicers make them 0.8 to 1.5 times it.
        if median < 0.55 * nozzle {
            self.diagnostics.add("filament-diameter", line, || {
                format!(
                    "the file states no filament diameter and its walls read {median:.2} mm wide at 1.75 mm (nozzle {nozzle} mm): if the printer takes 2.85 mm filament, set SLIC3R_FILAMENT_DIAMETER=2.85"
                )
            });
        }
    }

    fn complete(&mut self, b: Builder) -> Layer {
        let is_layer = b.kind == LayerKind::Layer;
        let moved = b.e_forward + b.e_back;
        if is_layer
            && self.printed
            && self.e_backwards.is_none()
            && match self.facts.slicer {
                // (Versions that wiped without tags are not judged: a wipe was tagged.)
                Slicer::PrusaSlicer
                | Slicer::SuperSlicer
                | Slicer::OrcaSlicer
                | Slicer::BambuStudio
                | Slicer::CrealityPrint => self.wipes_tagged,
                Slicer::Cura => true,
                _ => false,
            }
            && moved >= E_BACK_MIN_MM
            && b.e_back > E_BACK_SHARE * moved
        {
            self.e_backwards = Some((b.first_line, b.e_back / moved));
        }
        let z = b
            .z_tag
            .or(b.extrusion_z)
            .unwrap_or(if is_layer { self.prev_layer_z } else { 0.0 });
        let height = if !is_layer {
            0.0
        } else if let Some(h) = b.height_tag {
            h
        } else if z - self.prev_layer_z > Z_EPS {
            z - self.prev_layer_z
        } else {
            self.config_layer_height.unwrap_or(z.max(0.0))
        };
        let mut paths = b.paths;
        // A layer marker's height may be the step from the layer before (PrusaSlicer's
        // `;HEIGHT:` where objects of different layer heights interleave: 0.05 for a 0.2 mm
        // layer) while each extrusion states its own: the beads decide.
        // Bridges laid with a round bead (PrusaSlicer's thick bridges: 0.39 mm tall in a
        // 0.2 mm layer) hang into the air under the layer: they say nothing of its height nor
        // of what it rests on, unless the layer holds nothing else.
        let layer_beads = || paths.iter().filter(|p| !p.role.is_bridge_flow());
        let bead = match bead_height(layer_beads()) {
            0.0 => bead_height(&paths),
            b => b,
        };
        let height = if is_layer && bead > height * 1.1 + 1e-9 {
            bead
        } else {
            height
        };
        // What the layer rests on reaches down from its tallest bead (objects of different
        // layer heights sharing the layer: the tallest object's layer below is under it too).
        let reach = layer_beads()
            .map(|p| p.height)
            .filter(|h| *h <= MAX_HEIGHT)
            .fold(height, f64::max);
        for p in &mut paths {
            if p.height <= 0.0 {
                p.height = if height > 0.0 {
                    height
                } else {
                    self.config_layer_height.unwrap_or(0.2)
                };
            }
            if p.width <= 0.0 {
                p.width = p.e_width(self.filament_area);
            }
        }
        let index = self.next_index;
        if is_layer && index >= 1 {
            self.sample_walls(&paths, b.last_line);
        }
        let mut rests = Vec::new();
        let mut contact = Vec::new();
        let mut gap_below = Vec::new();
        let mut walls_on_previous = false;
        if is_layer {
            rests = rests_on(&self.recent, z, reach);
            walls_on_previous = index >= 1 && rests_on(&self.recent, z, height) == [index - 1];
            if !self.recent_support.is_empty() {
                let support = |i: usize| {
                    let s = self.recent_support.iter().find(|s| s.0 == i);
                    s.map(|s| s.1)
                };
                contact = contact_under(&self.recent, support, &rests, z, reach);
            }
            if paths.iter().any(|p| p.role.is_support()) {
                gap_below = gap_under(&self.recent, &rests, z, reach);
            }
            if self.recent.len() == RECENT_LAYERS {
                if let Some((gone, _)) = self.recent.pop_front() {
                    self.recent_support.retain(|s| s.0 != gone);
                }
            }
            self.recent.push_back((index, z));
            if paths.iter().any(|p| p.role.is_support()) {
                let alone = paths
                    .iter()
                    .all(|p| p.role.is_support() || !p.role.is_part());
                self.recent_support.push((index, alone));
            }
            self.next_index += 1;
            self.prev_layer_z = z;
            self.last_height = height;
        }
        let mut layer = Layer {
            kind: b.kind,
            index: if is_layer { index } else { 0 },
            marker_number: b.marker_number,
            z,
            height,
            rests_on: rests,
            walls_on_previous,
            contact,
            gap_below,
            helical: b.helical,
            spread: 0.0,
            paths,
            first_line: b.first_line,
            last_line: b.last_line,
            raw: b.raw,
            start: b.start,
            objects: std::mem::take(&mut self.objects_changed).then(|| self.objects.clone()),
        };
        if layer.on_bed() {
            layer.spread = self.first_layer_spread;
        }
        layer
    }

    fn finish_input(&mut self) {
        let next = self.cur.last_line.wrapping_add(1);
        if self.cur.last_line.wrapping_add(1) != self.cur.first_line
            || self.cur.kind == LayerKind::Layer
        {
            self.finish_current(next);
        }
        if self.facts.layer_source == LayerSource::Undecided {
            if self.held.is_empty() {
                self.facts.layer_source = LayerSource::InferredFromZ;
            } else {
                self.settle_inferred();
            }
        }
    }
}

impl<R: BufRead> Iterator for LayerReader<R> {
    type Item = io::Result<Layer>;

    fn next(&mut self) -> Option<Self::Item> {
        loop {
            if let Some(l) = self.st.ready.pop_front() {
                return Some(Ok(l));
            }
            if self.done {
                return None;
            }
            match self.pump() {
                Ok(true) => {}
                Ok(false) => {
                    self.done = true;
                    self.st.finish_input();
                }
                Err(e) => {
                    self.done = true;
                    return Some(Err(e));
                }
            }
        }
    }
}

/// Literal layers and strands for unit tests across the crate.
#[cfg(test)]
pub(crate) mod testing {
    use super::{Layer, LayerKind, Path, Role};

    /// A xorshift generator from `seed` (not zero): the same cases on every run.
    pub fn xorshift(mut seed: u64) -> impl FnMut() -> u64 {
        move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed
        }
    }

    /// A strand `width` wide along `pts`, 0.2 mm high (segments from line 1, 0.01 mm of E).
    pub fn path(role: Role, width: f64, pts: &[[f64; 2]]) -> Path {
        Path {
            role,
            width,
            height: 0.2,
            z: 0.2,
            object: None,
            tool: 0,
            points: pts.to_vec(),
            seg_line: vec![1; pts.len().saturating_sub(1)],
            seg_e: vec![0.01; pts.len().saturating_sub(1)],
            feed: 1200.0,
        }
    }

    /// Layer `index` (0-based), 0.2 mm layers, of `paths`.
    pub fn layer(index: usize, paths: Vec<Path>) -> Layer {
        Layer {
            kind: LayerKind::Layer,
            index,
            marker_number: None,
            z: 0.2 * (index + 1) as f64,
            height: 0.2,
            rests_on: index.checked_sub(1).into_iter().collect(),
            walls_on_previous: index >= 1,
            contact: Vec::new(),
            gap_below: Vec::new(),
            helical: false,
            spread: 0.0,
            paths,
            first_line: 1,
            last_line: 1,
            raw: Vec::new(),
            start: None,
            objects: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(src: &str, keep_raw: bool) -> (Vec<Layer>, FileFacts) {
        let mut r = LayerReader::new(
            src.as_bytes(),
            ReaderOptions {
                keep_raw,
                ..Default::default()
            },
        );
        let layers: Vec<Layer> = r.by_ref().map(|l| l.unwrap()).collect();
        (layers, r.facts().clone())
    }

    fn layers_only(v: &[Layer]) -> Vec<&Layer> {
        v.iter().filter(|l| l.kind == LayerKind::Layer).collect()
    }

    const PRUSA: &str = "; generated by PrusaSlicer 2.5.0 on x\nG90\nM83\nG1 Z0.2\n\
G1 X0 Y0\nG1 X60 E9 ; intro line\n;LAYER_CHANGE\n;Z:0.2\n;HEIGHT:0.2\n;TYPE:External perimeter\n\
;WIDTH:0.45\nG1 X10 Y0\nG1 X20 Y0 E0.5\nG1 X20 Y10 E0.5\n;TYPE:Internal infill\nG1 X10 Y10 E0.5\n\
;LAYER_CHANGE\n;Z:0.4\n;HEIGHT:0.2\nG1 Z0.4\n;TYPE:External perimeter\nG1 X10 Y0 E0.5\nM107\n";

    #[test]
    fn a_move_with_a_word_that_is_no_number_is_noted() {
        let src = format!("{PRUSA}G1 XNaN Y20 E1\nG1 Xinf E1\nM117 Hello world\n");
        let mut r = LayerReader::new(src.as_bytes(), ReaderOptions::default());
        for l in r.by_ref() {
            l.unwrap();
        }
        let d = r.diagnostics();
        assert!(d.has("bad-move"));
        let notes = d.list();
        let (line, text, count) = notes.iter().find(|n| n.1.contains("no number")).unwrap();
        let first = PRUSA.lines().count() as u64 + 1;
        assert_eq!((*line, *count), (first, 2), "{notes:?}");
        assert!(text.contains("`G1 XNaN Y20 E1`"), "{text}");
        // A message command's text is no move.
        assert!(!notes.iter().any(|n| n.1.contains("M117")), "{notes:?}");
    }

    #[test]
    fn kiri_moto_pushes_relative_e_without_saying_m83() {
        let kiri = "; Generated by Kiri:Moto 4.7.1\nG90\nG1 Z0.2\nG1 X0 Y0\n\
G1 X10 Y0 E0.5\nG1 X20 Y0 E0.5\nG1 X20 Y10 E0.4\n";
        let (layers, facts) = read(kiri, false);
        assert_eq!(facts.slicer, Slicer::KiriMoto);
        let e: Vec<f64> = layers
            .iter()
            .flat_map(|l| l.paths.iter().flat_map(|p| p.seg_e.iter().copied()))
            .collect();
        assert_eq!(e, vec![0.5, 0.5, 0.4]);
        // A file that says M82 keeps it.
        let (layers, _) = read(&kiri.replace("G90\n", "G90\nM82\n"), false);
        let e: Vec<f64> = layers
            .iter()
            .flat_map(|l| l.paths.iter().flat_map(|p| p.seg_e.iter().copied()))
            .collect();
        assert_eq!(e, vec![0.5]);
    }

    #[test]
    fn prusa_markers_roles_widths() {
        let (layers, facts) = read(PRUSA, true);
        assert_eq!(facts.slicer, Slicer::PrusaSlicer);
        assert_eq!(facts.layer_source, LayerSource::Markers);
        let ls = layers_only(&layers);
        assert_eq!(ls.len(), 2);
        assert_eq!(ls[0].z, 0.2);
        assert_eq!(ls[1].z, 0.4);
        assert_eq!(ls[0].paths.len(), 2);
        assert_eq!(ls[0].paths[0].role, Role::ExternalPerimeter);
        assert_eq!(ls[0].paths[0].width, 0.45);
        assert_eq!(ls[0].paths[0].points.len(), 3);
        assert_eq!(ls[0].paths[1].role, Role::Infill);
        assert_eq!(layers[0].kind, LayerKind::Preamble);
        assert_eq!(layers[0].paths[0].role, Role::WipePrime);
        let raw: Vec<u8> = layers.iter().flat_map(|l| l.raw.clone()).collect();
        assert_eq!(raw, PRUSA.as_bytes());
    }

    #[test]
    fn stripped_comments_infer_same_layers() {
        let stripped: String = PRUSA
            .lines()
            .map(|l| l.split(';').next().unwrap().trim_end())
            .filter(|l| !l.is_empty())
            .map(|l| format!("{l}\n"))
            .collect();
        let (layers, facts) = read(&stripped, true);
        assert_eq!(facts.layer_source, LayerSource::InferredFromZ);
        let ls = layers_only(&layers);
        assert_eq!(ls.len(), 2);
        assert!((ls[1].z - 0.4).abs() < 1e-9);
        let raw: Vec<u8> = layers.iter().flat_map(|l| l.raw.clone()).collect();
        assert_eq!(raw, stripped.as_bytes());
        // Width from E by the flow model: 0.5 mm of 1.75 filament over 10 mm at h = 0.2.
        let w = ls[1].paths[0].width;
        let expected =
            0.5 * filament_area(1.75) / 10.0 / 0.2 + 0.2 * (1.0 - std::f64::consts::FRAC_PI_4);
        assert!((w - expected).abs() < 1e-9);
    }

    #[test]
    fn z_hops_do_not_start_layers() {
        let src = "M83\nG1 Z0.2\nG1 X10 E1\nG1 Z0.6\nG1 X20 Y20\nG1 Z0.2\nG1 X30 E1\nG1 Z0.4\nG1 X40 E1\n";
        let (layers, _) = read(src, true);
        let ls = layers_only(&layers);
        assert_eq!(ls.len(), 2);
        assert_eq!(ls[0].paths.len(), 2);
        // The second layer starts at its Z move.
        assert_eq!(ls[1].first_line, 8);
    }

    #[test]
    fn cura_marker_after_z_move_and_mesh_labels() {
        let src = ";FLAVOR:Marlin\n;Generated with Cura_SteamEngine 4.13.0\nM82\n;LAYER:0\n;MESH:cube.stl\n\
G0 Z0.2\n;TYPE:WALL-OUTER\nG1 X10 E1\nG0 Z0.4\n;LAYER:1\n;TYPE:SKIN\nG1 X0 E2\n;BRIDGE\nG1 X-10 E3\n";
        let (layers, facts) = read(src, false);
        assert_eq!(facts.slicer, Slicer::Cura);
        let ls = layers_only(&layers);
        assert_eq!(ls.len(), 2);
        assert_eq!(ls[1].marker_number, Some(1));
        assert!((ls[1].z - 0.4).abs() < 1e-9);
        assert_eq!(ls[0].paths[0].role, Role::ExternalPerimeter);
        assert_eq!(ls[0].paths[0].object, Some(0));
        assert_eq!(ls[1].paths[0].role, Role::SolidInfill);
        assert_eq!(ls[1].paths[1].role, Role::BridgeInfill);
    }

    #[test]
    fn spiral_vase_is_one_layer_per_height() {
        let mut src = String::from("M83\nG1 Z0.2\nG1 X10 E1\n");
        // Ten revolutions, each rising 0.2 mm over four moves.
        let mut z = 0.2;
        for _ in 0..10 {
            for (x, y) in [(10.0, 10.0), (0.0, 10.0), (0.0, 0.0), (10.0, 0.0)] {
                z += 0.05;
                src.push_str(&format!("G1 X{x} Y{y} Z{z:.3} E0.3\n"));
            }
        }
        let (layers, facts) = read(&src, false);
        assert!(facts.spiral_vase);
        let n = layers_only(&layers).len();
        assert!((10..=12).contains(&n), "{n}");
    }

    #[test]
    fn klipper_and_m486_objects() {
        let src = "M83\nEXCLUDE_OBJECT_START NAME=part_1\nG1 Z0.2\nG1 X10 E1\nEXCLUDE_OBJECT_END NAME=part_1\n\
M486 S3\nM486 Abox\nG1 X20 E1\nM486 S-1\n";
        let mut r = LayerReader::new(src.as_bytes(), ReaderOptions::default());
        let layers: Vec<Layer> = r.by_ref().map(|l| l.unwrap()).collect();
        let ls = layers_only(&layers);
        assert_eq!(
            r.objects(),
            vec!["part_1".to_string(), "box (id 3)".to_string()]
        );
        assert_eq!(ls[0].paths[0].object, Some(0));
        assert_eq!(ls[0].paths[1].object, Some(1));
    }

    #[test]
    fn empty_and_garbage_input() {
        let (layers, _) = read("", true);
        assert!(layers_only(&layers).is_empty());
        let (layers, _) = read("\u{1}\u{2}garbage\nG1 X\n;;;\n", true);
        assert!(layers_only(&layers).is_empty());
        let raw: Vec<u8> = layers.iter().flat_map(|l| l.raw.clone()).collect();
        assert_eq!(raw, "\u{1}\u{2}garbage\nG1 X\n;;;\n".as_bytes());
    }

    #[test]
    fn relative_e_from_config_without_m83() {
        let mut cfg = SlicerConfig::default();
        cfg.apply_env([("SLIC3R_USE_RELATIVE_E_DISTANCES".into(), "1".into())]);
        let src = "G1 Z0.2\nG1 X10 E1\nG1 X20 E1\n";
        let mut r = LayerReader::new(
            src.as_bytes(),
            ReaderOptions {
                keep_raw: false,
                config: cfg,
            },
        );
        let layers: Vec<Layer> = r.by_ref().map(|l| l.unwrap()).collect();
        let e: f64 = layers.iter().flat_map(|l| &l.paths).map(|p| p.e()).sum();
        assert!((e - 2.0).abs() < 1e-9);
    }

    #[test]
    fn a_layer_rests_on_the_layers_whose_top_is_at_its_bottom() {
        let recent = |v: &[(usize, f64)]| v.iter().copied().collect::<VecDeque<_>>();
        // One layer height: the layer before.
        assert_eq!(rests_on(&recent(&[(0, 0.2), (1, 0.4)]), 0.6, 0.2), vec![1]);
        // 0.2 mm and 0.15 mm objects interleaved: Z 0.4 of the first rests on its layer at
        // 0.2 and on the other's at 0.35.
        assert_eq!(
            rests_on(&recent(&[(0, 0.2), (1, 0.35)]), 0.4, 0.2),
            vec![1, 0]
        );
        // Another object's part of the same layer (KISSlicer writes one layer per object).
        assert_eq!(rests_on(&recent(&[(0, 0.2), (1, 0.4)]), 0.4, 0.2), vec![0]);
        // Sequential printing: the second copy's second layer rests on its first only.
        assert_eq!(
            rests_on(&recent(&[(0, 0.2), (1, 10.0), (2, 0.2)]), 0.4, 0.2),
            vec![2]
        );
        // A gap under the layer: the layer before, as for any file.
        assert_eq!(rests_on(&recent(&[(0, 0.2)]), 1.0, 0.2), vec![0]);
        assert!(rests_on(&recent(&[]), 0.2, 0.2).is_empty());
    }

    #[test]
    fn support_stands_on_the_part_across_its_bottom_gap() {
        // Part layers up to Z 2.0 (0.2 mm), a layer of walls only at 2.2 (rests on 2.0), then
        // support from Z 2.4 standing on the part's top at 2.0 across one empty layer.
        let r: VecDeque<(usize, f64)> = (0..10).map(|i| (i, 0.2 * (i + 1) as f64)).collect();
        // Layer 11 (Z 2.4) rests on layer 10 (Z 2.2, not in `recent` here): the layers
        // under it within the gap, nearest first, two at most.
        assert_eq!(gap_under(&r, &[], 2.4, 0.2), vec![9, 8]);
        // Past the gap: nothing.
        let far: VecDeque<(usize, f64)> = (0..5).map(|i| (i, 0.2 * (i + 1) as f64)).collect();
        assert!(gap_under(&far, &[], 2.4, 0.2).is_empty());
        // The layer it rests on is not one of them; a layer above it (sequential printing
        // coming back down) ends the walk.
        assert_eq!(gap_under(&r, &[9], 2.2, 0.2), vec![8, 7]);
        let seq: VecDeque<(usize, f64)> = VecDeque::from(vec![(0, 1.8), (1, 5.0)]);
        assert!(gap_under(&seq, &[], 2.2, 0.2).is_empty());
    }

    #[test]
    fn support_holds_a_layer_across_its_contact_gap() {
        let recent = |v: &[(usize, f64)]| v.iter().copied().collect::<VecDeque<_>>();
        // A part at 0.3 mm layers; support on layers 0 and 1. The layer at 1.2 stands 0.3 mm
        // over layer 1's support, 0.6 mm over layer 0's (too deep to hold it).
        let r = recent(&[(0, 0.3), (1, 0.6), (2, 0.9)]);
        let part_and_support = |i: usize| (i <= 1).then_some(false);
        assert_eq!(contact_under(&r, part_and_support, &[2], 1.2, 0.3), vec![1]);
        assert!(contact_under(&r, |i| (i == 0).then_some(false), &[2], 1.2, 0.3).is_empty());
        // A first layer over a raft (0.2, 0.45, 0.5) and a support-only layer at 0.695 under
        // the part's tip: it rests on the support layer, and through it on the whole raft.
        let raft = recent(&[(0, 0.2), (1, 0.4476), (2, 0.5), (3, 0.6951)]);
        let alone = |_| Some(true);
        assert_eq!(
            contact_under(&raft, alone, &[3], 0.9, 0.2049),
            vec![2, 1, 0]
        );
        // Cura prints the first layer over its raft (layer 3) higher than the next one, which
        // rests on the support under it all the same.
        let cura = recent(&[(0, 0.65), (1, 0.93), (2, 1.15)]);
        let support = |i| (i < 2).then_some(true);
        assert_eq!(contact_under(&cura, support, &[2], 1.08, 0.15), vec![1, 0]);
        // Sequential printing: an object printed before, higher up, ends the walk.
        let seq = recent(&[(0, 0.2), (1, 10.0), (2, 0.2)]);
        assert!(contact_under(&seq, |i| (i == 1).then_some(true), &[2], 0.4, 0.2).is_empty());
    }

    #[test]
    fn kisslicer_layers_per_object_get_their_thickness_and_what_they_rest_on() {
        // Two objects, 0.3 mm and 0.1 mm layers, one marker per object and layer.
        let mut src = String::from("; KISSlicer - PRO\nG21\nG90\nM82\n");
        let mut e = 0.0;
        let mut layer = |src: &mut String, x: f64, z: f64, h: f64| {
            src.push_str(&format!(
                "; BEGIN_LAYER_OBJECT z={z:.3} z_thickness={h:.3}\nG1 X{x} Y0 Z{z:.3} F3000\n"
            ));
            e += 1.0;
            src.push_str(&format!("G1 X{} Y0 E{e:.3}\n", x + 10.0));
        };
        for k in 1..=6 {
            let z = 0.1 * k as f64;
            if k % 3 == 0 {
                layer(&mut src, 0.0, z, 0.3);
            }
            layer(&mut src, 50.0, z, 0.1);
        }
        let (layers, facts) = read(&src, false);
        assert_eq!(facts.layer_source, LayerSource::Markers);
        let l = layers_only(&layers);
        let zs: Vec<(f64, f64)> = l.iter().map(|l| (l.z, l.height)).collect();
        assert_eq!(l.len(), 8, "{zs:?}");
        // The 0.3 mm object's second layer (Z 0.6) rests on the thin object's layers at 0.4
        // and 0.5 and on its own at 0.3 (and the thin one's there), not on its sibling at 0.6.
        let thick = l.iter().rfind(|l| (l.height - 0.3).abs() < 1e-9).unwrap();
        assert!((thick.z - 0.6).abs() < 1e-9, "{zs:?}");
        let tops: Vec<f64> = thick.rests_on.iter().map(|&i| l[i].z).collect();
        assert_eq!(tops.len(), 4, "{tops:?}");
        assert!(tops.iter().all(|&t| t > 0.29 && t < 0.51), "{tops:?}");
        // The thin object's layer at 0.6 skips its sibling and rests on the layer at 0.5.
        let thin = l.last().unwrap();
        assert!((thin.height - 0.1).abs() < 1e-9 && thin.rests_on.len() == 1);
        assert!((l[thin.rests_on[0]].z - 0.5).abs() < 1e-9);
    }

    #[test]
    fn a_layer_height_tag_that_is_the_step_gives_way_to_the_beads_height() {
        // PrusaSlicer, objects at 0.2 and 0.15 mm: `;HEIGHT:` at the layer change is the step
        // from the layer before (0.05), each extrusion then states its own.
        let src = ";LAYER_CHANGE\n;Z:0.2\n;HEIGHT:0.2\nG1 Z0.2\nG1 X0 Y0\nG1 X10 E1\n\
                   ;LAYER_CHANGE\n;Z:0.35\n;HEIGHT:0.15\nG1 Z0.35\nG1 X50 Y0\nG1 X60 E2\n\
                   ;LAYER_CHANGE\n;Z:0.4\n;HEIGHT:0.05\nG1 Z0.4\n;HEIGHT:0.2\nG1 X0 Y0\nG1 X10 E3\n";
        let (layers, _) = read(src, false);
        let l = layers_only(&layers);
        assert_eq!(l.len(), 3);
        assert!((l[2].height - 0.2).abs() < 1e-9, "{}", l[2].height);
        assert_eq!(l[2].rests_on, vec![1, 0]);
        assert!(!l[2].on_previous() && l[1].on_previous());
    }

    #[test]
    fn thick_bridges_hang_below_the_layer_they_are_printed_in() {
        // PrusaSlicer's thick bridges: the overhang perimeter's round bead is 0.39 mm tall in
        // a 0.2 mm layer, and carries most of the layer's length. The layer is 0.2 mm and
        // rests on the layer before it alone.
        let src = ";LAYER_CHANGE\n;Z:0.2\n;HEIGHT:0.2\nG1 Z0.2\nG1 X0 Y0\nG1 X10 E1\n\
                   ;LAYER_CHANGE\n;Z:0.4\n;HEIGHT:0.2\nG1 Z0.4\nG1 X0 Y0\nG1 X10 E2\n\
                   ;LAYER_CHANGE\n;Z:0.6\n;HEIGHT:0.2\nG1 Z0.6\n;TYPE:External perimeter\n\
                   G1 X0 Y0\nG1 X10 E3\n;TYPE:Overhang perimeter\n;HEIGHT:0.389872\n\
                   G1 X10 Y30 E5\n";
        let (layers, _) = read(src, false);
        let l = layers_only(&layers);
        assert_eq!(l.len(), 3);
        assert!((l[2].height - 0.2).abs() < 1e-9, "{}", l[2].height);
        assert_eq!(l[2].rests_on, vec![1]);
        // The bead keeps its own height.
        assert!(l[2]
            .paths
            .iter()
            .any(|p| (p.height - 0.389872).abs() < 1e-9));
    }

    #[test]
    fn height_comments_out_of_range_are_ignored() {
        let src = ";LAYER_CHANGE\n;Z:0.2\n;HEIGHT:1e300\nG1 Z0.2\nG1 X0 Y0\nG1 X10 E1\n\
                   ;LAYER_CHANGE\n;Z:0.4\n;HEIGHT:-5\nG1 Z0.4\nG1 X0 Y0 E2\n";
        let (layers, _) = read(src, false);
        let l = layers_only(&layers);
        assert_eq!(l.len(), 2);
        assert!(
            l.iter().all(|l| l.height > 0.0 && l.height <= 0.4),
            "{:?}",
            l.iter().map(|l| l.height).collect::<Vec<_>>()
        );
        assert!(l.iter().flat_map(|l| &l.paths).all(|p| p.height <= 0.4));
    }
}
