//! Stage 6: write the rewritten G-code, changing only what the plan changes.
//!
//! Input: a layer with its raw bytes and the interpreter state at its start, and the [`Plan`]s
//! of its regions. Output: the layer's new bytes and what changed.
//!
//! Invariants:
//! - A line is copied byte for byte unless it is an extrusion of the part that crosses a plan's
//!   zone. Such a line is split where it crosses the zone: the parts outside keep their path
//!   and their share of the line's E; the parts inside become travel moves.
//! - Each region's strands are written as one block, inserted before the first line that
//!   crosses its zone. The block leaves the machine as it found it: position, feedrate, fan,
//!   retraction, and in absolute-E mode the E counter (re-synced with G92).
//! - E bookkeeping is exact in both M82 and M83: every line outside the changes extrudes
//!   exactly what it did.
//! - The one other change: an infill end beside a zone that the deposition check would find
//!   hanging over air (judged against the layer below as written, read back when poa
//!   rewrote it) gets a short anchor onto material that holds it, or is cut back when nothing
//!   is near and nothing printed later rests on it; that is why a layer is rewritten only once
//!   the layer above it has been read.

use std::io::{self, BufRead, Write};

use geo::MultiPolygon;
use serde::Serialize;

use crate::error::Error;
use crate::gcode::{parse_line, split_lines, strip_terminator};
use crate::geometry::{RegionKind, RingIndex};
use crate::layers::{flow_width, Layer, Role, SlicerConfig};
use crate::machine::{Action, Machine};
use crate::pass::Pass;
use crate::poa::{polyline_length, BridgeMode, Plan, PoaSettings, Strand, StrandKind};
use crate::progress::footer_line;
pub use crate::progress::update_footer;
use crate::writer::{fmt_num, MmPerMin, MmPerS, TravelStyle, Writer};

/// Where the rewrite's text goes, block by block, in order: a block is a stretch of the input
/// as it was read (`from_input`: its byte offset in the input) or bytes the rewrite made
/// (`None`). Concatenated, the blocks are the output.
pub trait Sink {
    fn block(&mut self, bytes: &[u8], from_input: Option<u64>) -> io::Result<()>;
}

/// A [`Sink`] that writes every block to a writer.
pub struct Plain<W>(pub W);

impl<W: Write> Sink for Plain<W> {
    fn block(&mut self, bytes: &[u8], _: Option<u64>) -> io::Result<()> {
        self.0.write_all(bytes)
    }
}

/// How the file moves between strands (its [`TravelStyle`]) and how fast poa prints.
#[derive(Debug, Clone)]
pub struct Motion {
    pub filament_area: f64,
    pub travel: TravelStyle,
    /// Loop and perimeter speeds, resolved from the settings and the file.
    pub loop_speed: MmPerS,
    pub perimeter_speed: MmPerS,
    /// Slowest speed a loop is slowed to for cooling ([`slowed_for_cooling`]).
    pub cooling_floor: MmPerS,
}

impl Motion {
    pub fn from_config(config: &SlicerConfig, settings: &PoaSettings) -> Motion {
        // A speed of 0 in the file (which the ranges let through as the slicer's "auto")
        // says nothing: the default, not 1 mm/s loops.
        let loop_speed = settings
            .loop_speed
            .or_else(|| config.number("bridge_speed").filter(|v| *v > 0.0))
            .unwrap_or(25.0)
            .max(1.0);
        Motion {
            filament_area: config.e_area(),
            travel: TravelStyle::from_config(config),
            loop_speed: MmPerS(loop_speed),
            perimeter_speed: MmPerS(settings.perimeter_speed.unwrap_or(loop_speed).max(1.0)),
            // The slicer's own floor for cooling where it states one: a user who keeps
            // PrusaSlicer from printing slower than 10 mm/s gets no 5 mm/s loops from poa
            // either (a wheel's 0.4 mm ladder rungs at 5 mm/s were half its one rewritten
            // layer's time, and could not take their half second even so).
            cooling_floor: MmPerS(
                settings
                    .min_loop_speed
                    .or_else(|| config.cooling_min_speed().map(|v| v.max(COOLING_FLOOR.0)))
                    .unwrap_or(COOLING_FLOOR.0)
                    .max(1.0),
            ),
        }
    }

    /// Filament per mm of path for a bead of `width` at `height` (Slic3r flow model).
    pub fn e_per_mm(&self, width: f64, height: f64, flow_factor: f64) -> f64 {
        let area = (width - height) * height + std::f64::consts::PI * height * height / 4.0;
        area.max(0.0) / self.filament_area * flow_factor
    }
}

/// One region to rewrite in a layer.
#[derive(Clone)]
pub struct RegionRewrite {
    /// 1-based, file-wide.
    pub id: usize,
    pub kind: RegionKind,
    pub plan: Plan,
    /// Bead height of the rewrite (mm): the height the slicer laid the region's object at on
    /// this layer (objects of different layer heights share a layer).
    pub height: f64,
    /// Where loops are not joined by extruded connectors: round an anchor strip over sparse
    /// infill ([`anchor_strips`]) nothing older than the loops just laid holds a step between
    /// them (empty elsewhere).
    pub no_connect: MultiPolygon<f64>,
}

/// What a region's rewrite changed.
#[derive(Debug, Clone, Default, Serialize)]
pub struct RewriteStats {
    pub region: usize,
    pub layer: usize,
    pub z: f64,
    pub loops: usize,
    pub strands: usize,
    /// A gradual overhang: its external perimeter moved to bite into the layer below (with
    /// a half-width loop under it where it would hang farther).
    pub gradual: bool,
    /// Length of the strands poa wrote (mm).
    pub written_length_mm: f64,
    pub written_filament_mm: f64,
    /// Original extrusion taken out of the zone.
    pub removed_length_mm: f64,
    pub removed_filament_mm: f64,
    /// Travel poa added (mm), into and out of the block included.
    pub travel_mm: f64,
    /// Of that, travel between the block's own strands (mm): what joining loops saves.
    pub inner_travel_mm: f64,
    /// The longest of those travels (mm): a narrow region whose outline meets it at two far
    /// ends (an arch's crown) crosses it once, between finishing one end and the other.
    pub longest_inner_travel_mm: f64,
    /// Loops reached from the one before by an extruded connector instead of a travel.
    pub connectors: usize,
    /// Estimated time added (s), before acceleration: new strands and travel minus what the
    /// removed extrusion took.
    pub time_added_s: f64,
    /// Of that, pauses after loops (`--dwell`), which the motion estimator does not see.
    pub dwell_s: f64,
    /// Line before which the block was inserted (input numbering).
    pub inserted_before_line: u64,
    /// Sparse-infill ends beside the region that hung over air: cut back (lines), or
    /// anchored on material close by.
    pub trimmed_ends: usize,
    pub anchored_ends: usize,
}

/// A line ending like the layer's own.
fn line_end(raw: &[u8]) -> &'static str {
    match memchr::memchr(b'\n', raw) {
        Some(i) if i > 0 && raw[i - 1] == b'\r' => "\r\n",
        _ => "\n",
    }
}

/// The layers `layer` rests on among `kept`, all of them, or none (no end anchored or cut).
fn resting_on<'a>(kept: &'a std::collections::VecDeque<Layer>, layer: &Layer) -> Vec<&'a Layer> {
    layer
        .rests_on
        .iter()
        .map(|&i| kept.iter().find(|b| b.index == i && b.kind == layer.kind))
        .collect::<Option<Vec<&Layer>>>()
        .unwrap_or_default()
}

/// The layers the deposition check judges `layer` on among `kept` ([`crate::check::resting_on`]):
/// those it rests on, and those whose support material holds it across the slicer's contact
/// gap. The rewrite's judges read these, as `poa check` does: judged on the layer it rests on
/// alone, a cap's first layer over Cura's support (a layer's gap under it) was all "in air"
/// as sliced and as rewritten, and a rewrite 1.7 mm worse on `poa check` passed.
fn judged_on<'a>(kept: &'a std::collections::VecDeque<Layer>, layer: &Layer) -> Vec<&'a Layer> {
    let below = resting_on(kept, layer);
    if below.is_empty() || (layer.contact.is_empty() && layer.gap_below.is_empty()) {
        return below;
    }
    crate::check::resting_on(layer, kept.iter())
}

/// Regions of a layer with their report numbers.
type Chosen<'r> = Vec<(usize, &'r crate::geometry::Region)>;

/// Roles whose strands inside a zone are replaced.
fn replaced(role: Role) -> bool {
    role.is_part()
}

/// The last `;TYPE:` and `;WIDTH:`-style lines seen, restored after a block so that G-code
/// viewers keep labelling the slicer's strands correctly; and the dialect they are in, which
/// the block's own tags follow.
#[derive(Default)]
struct Tags {
    role: Option<String>,
    width: Option<String>,
    /// PrusaSlicer's `;HEIGHT:`, which its thick bridges set to the round bead's height.
    height: Option<String>,
    /// Bambu Studio's tags (`; FEATURE:`, `; LINE_WIDTH:`), which OrcaSlicer also writes for
    /// Bambu printers: their viewers read no `;TYPE:`.
    feature_tags: bool,
    /// Role names of OrcaSlicer and Bambu Studio ("Outer wall"), in either tag style.
    orca_names: bool,
}

/// Role names only OrcaSlicer and Bambu Studio use (their `role_to_string`).
const ORCA_ROLES: &[&str] = &[
    "Outer wall",
    "Inner wall",
    "Overhang wall",
    "Bridge wall",
    "Sparse infill",
    "Internal solid infill",
    "Top surface",
    "Bottom surface",
    "Bridge",
    "Internal Bridge",
    "Gap infill",
    "Floating vertical shell",
    "Support transition",
    "Prime tower",
];

impl Tags {
    fn see(&mut self, content: &[u8]) {
        let t = content.trim_ascii();
        let text = || Some(String::from_utf8_lossy(t).into_owned());
        let role = t
            .strip_prefix(b";TYPE:")
            .or_else(|| t.strip_prefix(b"; FEATURE:"));
        if let Some(name) = role {
            self.role = text();
            self.feature_tags |= t.starts_with(b"; FEATURE:");
            let name = name.trim_ascii();
            self.orca_names |= ORCA_ROLES.iter().any(|r| r.as_bytes() == name);
        } else if t.starts_with(b";WIDTH:") || t.starts_with(b"; LINE_WIDTH:") {
            self.width = text();
            self.feature_tags |= t.starts_with(b"; LINE_WIDTH:");
        } else if t.starts_with(b";HEIGHT:") {
            self.height = text();
        } else if t == b"; CHANGE_LAYER" || t.starts_with(b"; Z_HEIGHT:") {
            // Bambu-style layer tags come first in a layer: a block before any role line
            // of its layer still speaks the file's dialect.
            self.feature_tags = true;
        }
    }

    /// The role line of poa's strands in the file's dialect: an overhang perimeter, which
    /// poa reads back as one in every dialect (Cura and Simplify3D name none: PrusaSlicer's
    /// name, which their viewers pass over).
    fn loops_role(&self) -> &'static str {
        match (self.feature_tags, self.orca_names) {
            (true, _) => "; FEATURE: Overhang wall",
            (false, true) => ";TYPE:Overhang wall",
            (false, false) => ";TYPE:Overhang perimeter",
        }
    }

    /// A width line in the file's dialect.
    fn width_line(&self, width: f64) -> String {
        let w = fmt_num(width, 3);
        if self.feature_tags {
            format!("; LINE_WIDTH: {w}")
        } else {
            format!(";WIDTH:{w}")
        }
    }
}

/// A layer rewritten with wide regions only (its outline where the slicer put it, less the
/// inset): its area as sliced, the zones rewritten and the strands laid there.
struct WideBelow {
    index: usize,
    area: MultiPolygon<f64>,
    zones: MultiPolygon<f64>,
    strands: Vec<(Vec<[f64; 2]>, f64)>,
}

/// Layers kept for what the next layers rest on ([`PoaPass::keep_below`]).
const KEEP_BELOW: usize = 8;

/// How far the area a rewritten layer is planned to print may reach past what it prints as
/// read back (mm): the two differ by the rounding of arcs and E.
const REREAD_SLACK: f64 = 0.02;
/// How far from the rewritten zones the splice may change a layer (a cut strand's end, an
/// anchor, a perimeter taken out with its region): past it the area read back is taken as
/// detected.
const AWAY_FROM_ZONES: f64 = 1.5;

/// Share of a plan's zone its strands may leave bare: a plan takes the slicer's strands out
/// of its whole zone, so one that fills little of it (perimeters only over a region wider
/// than a ring: a part's first layer over a raft, found over the support layer under its tip)
/// would drop the layer's solid infill and put nothing back. Loops leave 0-8 % bare (255
/// plans of the held-out slices).
const BARE_SHARE: f64 = 0.25;
/// Strands laying this many times their zone's area (length x width, overlaps counted
/// twice) fill it: loops overlapping by two fifths of a width cover 0.9 of it at 1.5.
const LAID_ENOUGH: f64 = 1.5;

/// Whether a plan (but a gradual overhang's) would leave more than [`BARE_SHARE`] of its
/// zone (and more than a square millimetre) with none of its strands.
fn leaves_a_hole(plan: &Plan) -> bool {
    use geo::Area;
    // A gradual overhang's thin ring is left bare in part by design: its moved perimeter
    // lies over the ring's outer side only.
    if plan.with_perimeter {
        return false;
    }
    let zone = plan.zone.unsigned_area();
    // Loops a step apart overlap by two fifths of a width: strands that fill the zone lay
    // about 1.7 times its area. Only a plan that lays less than [`LAID_ENOUGH`] times it is
    // buffered to measure (buffering every cap's loops cost a fifth of a plate's run).
    let laid_area: f64 = plan.strands.iter().map(|s| s.length() * s.width).sum();
    if laid_area >= LAID_ENOUGH * zone {
        return false;
    }
    let laid = crate::geometry::area::Strands::of_lines(
        plan.strands.iter().map(|s| (s.points.as_slice(), s.width)),
    )
    .buffer();
    let bare = crate::geometry::difference(&plan.zone, &laid).unsigned_area();
    bare > 1.0 && bare > BARE_SHARE * zone
}

/// Why a region is left as sliced when its strands rest on the layer below without loops.
pub const HELD_AS_SLICED: &str = "its strands rest on the layer below (no loop needed)";
/// Why a gradual overhang's region is left as sliced when its slicer perimeter holds.
pub const PERIMETER_HELD: &str = "the slicer's perimeter is held as sliced";

/// Layers whose external perimeter width [`PoaPass::width_on`] takes the median of.
const WALL_WIDTH_LAYERS: usize = 32;

/// Median width of a layer's external perimeters, if it has any.
fn median_wall_width(layer: &Layer) -> Option<f64> {
    let mut widths: Vec<f64> = layer
        .paths
        .iter()
        .filter(|p| p.role == crate::layers::Role::ExternalPerimeter)
        .map(|p| p.width)
        .filter(|w| w.is_finite() && *w > 0.0)
        .collect();
    if widths.is_empty() {
        return None;
    }
    let mid = widths.len() / 2;
    Some(*widths.select_nth_unstable_by(mid, f64::total_cmp).1)
}

/// Longest retraction (mm of filament) a block undoes and redoes: longer than any printer's
/// (Bowden printers retract up to about 10 mm).
const MAX_RETRACTION: f64 = 20.0;

/// Where a gradual overhang's block goes in the slicer's wall that crosses its zone.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BlockPlace {
    /// Where the wall enters the zone, ending where it leaves it: no travel out and back.
    AtEntry,
    /// Before the wall's move that enters the zone, returning to its start.
    BeforeMove,
}

/// Rewrites one layer. Returns the new bytes and per-region statistics.
///
/// Long by design: one pass over the layer's lines with the splice state (where the nozzle really is, open blocks, tags) that every branch updates; the branches themselves call helpers.
pub fn rewrite_layer(
    layer: &Layer,
    below: &[&Layer],
    above: Option<&Layer>,
    rewrites: &[RegionRewrite],
    motion: &Motion,
    settings: &PoaSettings,
    place: BlockPlace,
) -> (Vec<u8>, Vec<RewriteStats>) {
    let Some(start) = layer.start.as_deref() else {
        return (layer.raw.clone(), Vec::new());
    };
    let whole: Vec<&RegionRewrite> = rewrites
        .iter()
        .filter(|r| !r.plan.strands.is_empty())
        .collect();
    if whole.is_empty() {
        return (layer.raw.clone(), Vec::new());
    }
    // A gradual overhang's zone in pieces apart (a box's chamfer on two opposite sides) is
    // rewritten piece by piece, each block where the wall enters its piece: one block went
    // across the part between them.
    let parts: Vec<(usize, std::borrow::Cow<'_, RegionRewrite>)> = whole
        .iter()
        .enumerate()
        .flat_map(|(i, r)| by_zone_piece(r).into_iter().map(move |p| (i, p)))
        .collect();
    let owner: Vec<usize> = parts.iter().map(|(i, _)| *i).collect();
    let rewrites: Vec<&RegionRewrite> = parts.iter().map(|(_, r)| r.as_ref()).collect();
    // Which lines print part extrusions that may be replaced.
    let mut replaceable: Vec<u64> = layer
        .paths
        .iter()
        .filter(|p| replaced(p.role))
        .flat_map(|p| p.seg_line.iter().copied())
        .collect();
    replaceable.sort_unstable();
    replaceable.dedup();

    // Zone bounding boxes: most lines are nowhere near a zone. Every strand that crosses a
    // zone is cut at its edge: the parts outside (bridge infill anchored over the wall below,
    // sparse infill beside the region) stay, so the layer's printed area outside the region
    // is what the slicer made.
    let boxes: Vec<Option<geo::Rect<f64>>> = rewrites
        .iter()
        .map(|r| geo::BoundingRect::bounding_rect(&r.plan.zone))
        .collect();
    // Every extrusion near a zone is measured against it: its boundary in a grid.
    let zone_index: Vec<RingIndex> = rewrites
        .iter()
        .map(|r| RingIndex::new(&r.plan.zone))
        .collect();
    // The lines of external perimeters, where a gradual overhang's block goes.
    let perimeter_lines = wall_lines(layer);
    // Where the slicer's wall, after first entering a gradual overhang's zone, leaves it:
    // the block goes in where the wall enters and ends here, where the wall goes on (written
    // before the wall, it went out and back and the wall then jumped the zone: a 9 mm ring
    // on a 60 degree arm took 20 mm of travel, a retraction and a lift each way).
    let exits: Vec<Option<[f64; 2]>> = rewrites
        .iter()
        .zip(&zone_index)
        .map(|(r, index)| {
            if !r.plan.with_perimeter {
                return None;
            }
            layer
                .paths
                .iter()
                .filter(|p| matches!(p.role, Role::ExternalPerimeter | Role::OverhangPerimeter))
                .find_map(|p| {
                    inside_intervals(&p.points, index)
                        .first()
                        .map(|&(_, b)| point_at(&p.points, b))
                })
        })
        .collect();
    let tails = if below.is_empty() {
        Vec::new()
    } else {
        let zones: Vec<&MultiPolygon<f64>> = rewrites.iter().map(|r| &r.plan.zone).collect();
        dangling_tails(layer, below, above, &zones, &boxes, motion.filament_area)
    };
    let nl = line_end(&layer.raw);
    let mut machine: Machine = start.clone();
    let mut out = Vec::with_capacity(layer.raw.len() + 64 * 1024);
    let mut stats: Vec<RewriteStats> = rewrites
        .iter()
        .map(|r| RewriteStats {
            region: r.id,
            layer: layer.index + 1,
            z: layer.z,
            loops: r.plan.loops,
            strands: r.plan.strands.len(),
            gradual: r.plan.with_perimeter,
            ..Default::default()
        })
        .collect();
    let mut done = vec![false; rewrites.len()];
    let mut tags = Tags::default();
    let mut number = layer.first_line;
    // Where the nozzle really is while it differs from where the file believes it is (after
    // removed extrusion, until the next motion needs it back in step).
    let mut real: Option<[f64; 2]> = None;
    for raw in split_lines(&layer.raw) {
        let content = strip_terminator(raw);
        let parsed = parse_line(content);
        if parsed.comment.is_some() {
            tags.see(content);
        }
        let before = machine.snapshot();
        let action = machine.step(&parsed, number);
        let mut crossing = None;
        let mut fix = None;
        if let Action::Move(m) = &action {
            fix = tails
                .binary_search_by_key(&number, |t| t.line)
                .ok()
                // Anchors and cuts are written in absolute coordinates.
                .filter(|_| m.is_extrusion() && m.arc.is_none() && !before.xyz_relative());
            let cut = fix.filter(|&t| !tails[t].cut.is_empty());
            if let Some(t) = fix.filter(|&t| tails[t].before.is_some()) {
                resync(&mut out, nl, &before, &mut real, motion);
                let added = tails[t]
                    .before
                    .map(|q| anchor_before(&mut out, nl, &before, m, q, motion));
                let st = &mut stats[tails[t].region];
                st.anchored_ends += 1;
                if let Some((len, e)) = added {
                    st.written_length_mm += len;
                    st.written_filament_mm += e;
                    st.travel_mm += len;
                    st.time_added_s += len / (m.feed / 60.0).max(0.1)
                        + len / motion.travel.travel_speed.0.max(0.1);
                }
            }
            if m.is_extrusion() && (cut.is_some() || replaceable.binary_search(&number).is_ok()) {
                let pts = m.points(0.01);
                let (lo, hi) = pts.iter().fold(
                    ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]),
                    |(lo, hi), p| {
                        (
                            [lo[0].min(p[0]), lo[1].min(p[1])],
                            [hi[0].max(p[0]), hi[1].max(p[1])],
                        )
                    },
                );
                let hits: Vec<(usize, Vec<(f64, f64)>)> = rewrites
                    .iter()
                    .enumerate()
                    .filter(|(i, _)| {
                        boxes[*i].is_some_and(|b| {
                            hi[0] >= b.min().x
                                && lo[0] <= b.max().x
                                && hi[1] >= b.min().y
                                && lo[1] <= b.max().y
                        })
                    })
                    .map(|(i, _)| (i, inside_intervals(&pts, &zone_index[i])))
                    .filter(|(_, iv)| !iv.is_empty())
                    .collect();
                if !hits.is_empty() || cut.is_some() {
                    crossing = Some((*m, pts, hits, cut));
                }
            }
        }
        if let Some((m, pts, hits, cut)) = crossing {
            let on_perimeter = perimeter_lines.binary_search(&number).is_ok();
            // Gradual overhangs' blocks written where this move enters the zone.
            let mut at_entry: Vec<usize> = Vec::new();
            for (i, _) in &hits {
                if !done[*i] && (on_perimeter || !rewrites[*i].plan.with_perimeter) {
                    done[*i] = true;
                    stats[*i].inserted_before_line = number;
                    if place == BlockPlace::AtEntry
                        && exits[*i].is_some()
                        && m.arc.is_none()
                        && !before.xyz_relative()
                        && !before.is_retracted()
                    {
                        at_entry.push(*i);
                        continue;
                    }
                    resync(&mut out, nl, &before, &mut real, motion);
                    emit_block(
                        &mut out,
                        nl,
                        &before,
                        rewrites[*i],
                        motion,
                        settings,
                        &tags,
                        &mut stats[*i],
                        None,
                    );
                }
            }
            let mut all: Vec<(f64, f64)> =
                hits.iter().flat_map(|(_, iv)| iv.iter().copied()).collect();
            if let Some(t) = cut {
                all.extend(tails[t].cut.iter().copied());
            }
            all.sort_by(|a, b| a.0.total_cmp(&b.0));
            let all = merge_intervals(all);
            let mut entry = |out: &mut Vec<u8>, state: &Machine| {
                let mut state = state.snapshot();
                for &i in &at_entry {
                    let end = emit_block(
                        out,
                        nl,
                        &state,
                        rewrites[i],
                        motion,
                        settings,
                        &tags,
                        &mut stats[i],
                        exits[i],
                    );
                    state = state.partway(end, state.e_logical(), state.feedrate());
                }
                [state.position()[0], state.position()[1]]
            };
            let (len, e) = split_move(
                &mut out,
                nl,
                &mut real,
                motion,
                &before,
                &m,
                &pts,
                &all,
                content,
                (!at_entry.is_empty()).then_some(&mut entry as &mut EntryBlock),
            );
            // A cut end alone counts for the region it lies beside.
            let owners: Vec<usize> = if hits.is_empty() {
                cut.map(|t| tails[t].region).into_iter().collect()
            } else {
                hits.iter().map(|(i, _)| *i).collect()
            };
            let share = 1.0 / owners.len().max(1) as f64;
            for i in owners {
                stats[i].removed_length_mm += len * share;
                stats[i].removed_filament_mm += e * share;
                stats[i].time_added_s -= len * share / (m.feed / 60.0).max(0.1);
                if cut.is_some() {
                    stats[i].trimmed_ends += 1;
                }
            }
        } else {
            if let Action::Move(mv) = &action {
                let moves_xy = mv.from[0] != mv.to[0] || mv.from[1] != mv.to[1];
                if mv.is_extrusion() || before.xyz_relative() || mv.arc.is_some() {
                    // Where this move starts matters.
                    resync(&mut out, nl, &before, &mut real, motion);
                } else if moves_xy {
                    // An absolute travel ends where the file says, wherever it starts.
                    real = None;
                }
            }
            out.extend_from_slice(raw);
        }
        if let (Some(t), Action::Move(m)) = (fix, &action) {
            // Only from where the file's move ends: a move cut short ends elsewhere.
            if let (Some(q), None) = (tails[t].after, real) {
                let (len, e) = anchor_after(&mut out, nl, &machine, m, q);
                real = Some(q);
                let st = &mut stats[tails[t].region];
                st.anchored_ends += 1;
                st.written_length_mm += len;
                st.written_filament_mm += e;
                st.time_added_s += len / (m.feed / 60.0).max(0.1);
            }
        }
        number += 1;
    }
    // The layer ended inside a zone: put the nozzle where the file's last move ended.
    resync(&mut out, nl, &machine, &mut real, motion);
    // A gradual overhang whose zone no external perimeter crossed goes at the layer's end.
    for (i, r) in rewrites.iter().enumerate() {
        if !done[i] {
            stats[i].inserted_before_line = number;
            emit_block(
                &mut out,
                nl,
                &machine,
                r,
                motion,
                settings,
                &tags,
                &mut stats[i],
                None,
            );
        }
    }
    (out, merge_stats(stats, &owner))
}

/// A gradual overhang's rewrite split by the pieces of its zone that lie apart (farther than
/// [`PIECES_APART`]), each piece with the strands nearest it; any other rewrite whole.
fn by_zone_piece(r: &RegionRewrite) -> Vec<std::borrow::Cow<'_, RegionRewrite>> {
    use geo::{BoundingRect, Distance, Euclidean};
    let whole = || vec![std::borrow::Cow::Borrowed(r)];
    let polys = &r.plan.zone.0;
    if !r.plan.with_perimeter || polys.len() < 2 || polys.len() > MAX_PIECES {
        return whole();
    }
    // Pieces of the zone, grouped while any two come within reach of each other.
    let mut group: Vec<usize> = (0..polys.len()).collect();
    let boxes: Vec<Option<geo::Rect<f64>>> = polys.iter().map(|p| p.bounding_rect()).collect();
    for i in 0..polys.len() {
        for j in i + 1..polys.len() {
            let near =
                crate::geometry::boxes_within(boxes[i].as_ref(), boxes[j].as_ref(), PIECES_APART)
                    && (boxes[i].is_none()
                        || boxes[j].is_none()
                        || Euclidean.distance(&polys[i], &polys[j]) <= PIECES_APART);
            if near {
                let (gi, gj) = (group[i], group[j]);
                for g in group.iter_mut() {
                    if *g == gj {
                        *g = gi;
                    }
                }
            }
        }
    }
    let mut ids: Vec<usize> = group.clone();
    ids.sort_unstable();
    ids.dedup();
    if ids.len() < 2 {
        return whole();
    }
    // Each strand goes with the piece nearest its middle point.
    let mut strands: Vec<Vec<Strand>> = vec![Vec::new(); ids.len()];
    for s in &r.plan.strands {
        let Some(&mid) = s.points.get(s.points.len() / 2) else {
            continue;
        };
        let q = geo::Point::new(mid[0], mid[1]);
        let nearest = (0..polys.len())
            .min_by(|&a, &b| {
                Euclidean
                    .distance(&polys[a], &q)
                    .total_cmp(&Euclidean.distance(&polys[b], &q))
            })
            .unwrap_or(0);
        let k = ids.binary_search(&group[nearest]).unwrap_or(0);
        strands[k].push(s.clone());
    }
    // A piece with no strand of its own would lose the slicer's strands there: whole.
    if strands.iter().any(|s| s.is_empty()) {
        return whole();
    }
    ids.iter()
        .zip(strands)
        .map(|(&g, strands)| {
            let zone = MultiPolygon::new(
                polys
                    .iter()
                    .zip(&group)
                    .filter(|(_, &h)| h == g)
                    .map(|(p, _)| p.clone())
                    .collect(),
            );
            std::borrow::Cow::Owned(RegionRewrite {
                plan: Plan {
                    zone,
                    strands,
                    ..r.plan.clone()
                },
                ..r.clone()
            })
        })
        .collect()
}

/// Pieces of a gradual overhang's zone farther apart than this (mm) are written as blocks of
/// their own.
const PIECES_APART: f64 = 2.0;

/// Most pieces of a zone looked at for [`by_zone_piece`] (each pair is compared).
const MAX_PIECES: usize = 64;

/// The statistics of the pieces of each rewrite (`owner[k]`: the rewrite piece `k` is of)
/// added up, one per rewrite, in order.
fn merge_stats(stats: Vec<RewriteStats>, owner: &[usize]) -> Vec<RewriteStats> {
    let mut out: Vec<RewriteStats> = Vec::new();
    let mut last = None;
    for (s, &o) in stats.into_iter().zip(owner) {
        match out.last_mut().filter(|_| last == Some(o)) {
            Some(m) => {
                m.strands += s.strands;
                m.written_length_mm += s.written_length_mm;
                m.written_filament_mm += s.written_filament_mm;
                m.removed_length_mm += s.removed_length_mm;
                m.removed_filament_mm += s.removed_filament_mm;
                m.travel_mm += s.travel_mm;
                m.inner_travel_mm += s.inner_travel_mm;
                m.longest_inner_travel_mm =
                    m.longest_inner_travel_mm.max(s.longest_inner_travel_mm);
                m.connectors += s.connectors;
                m.time_added_s += s.time_added_s;
                m.dwell_s += s.dwell_s;
                m.inserted_before_line = m.inserted_before_line.min(s.inserted_before_line);
                m.trimmed_ends += s.trimmed_ends;
                m.anchored_ends += s.anchored_ends;
            }
            None => out.push(s),
        }
        last = Some(o);
    }
    out
}

/// The source lines of the layer's external (and overhang) perimeters, sorted.
fn wall_lines(layer: &Layer) -> Vec<u64> {
    lines_of(layer, |r| {
        matches!(r, Role::ExternalPerimeter | Role::OverhangPerimeter)
    })
}

/// The source lines of the layer's paths of the roles `keep` takes, sorted.
fn lines_of(layer: &Layer, keep: impl Fn(Role) -> bool) -> Vec<u64> {
    let mut lines: Vec<u64> = layer
        .paths
        .iter()
        .filter(|p| keep(p.role))
        .flat_map(|p| p.seg_line.iter().copied())
        .collect();
    lines.sort_unstable();
    lines
}

/// Before a strand's first move `m` (the nozzle where `state` says): a short travel to `q`
/// and an extrusion back to the start at the move's own E per mm, so that the strand starts
/// on material instead of over air. E is put back in step with the file after it. Returns
/// the anchor's length and filament.
fn anchor_before(
    out: &mut Vec<u8>,
    nl: &'static str,
    state: &Machine,
    m: &crate::machine::Move,
    q: [f64; 2],
    motion: &Motion,
) -> (f64, f64) {
    let (at, len, per_mm) = anchor_measure(state, m, q);
    let mut w = Writer::new(out, nl, state).at(at);
    w.line("; poa: anchor the strand's start");
    w.travel(&motion.travel, q, false);
    w.feed_to(MmPerMin(m.feed));
    w.extrude_to([at[0], at[1]], len * per_mm);
    w.restore_feed(MmPerMin(state.feedrate()));
    w.sync_e(state.e_logical());
    (len, len * per_mm)
}

/// After a strand's last move `m` (`state` after it): an extrusion on to `q` at the move's own
/// E per mm, so that the strand ends on material instead of over air. E is put back in step
/// with the file after it; the nozzle is left at `q`.
fn anchor_after(
    out: &mut Vec<u8>,
    nl: &'static str,
    state: &Machine,
    m: &crate::machine::Move,
    q: [f64; 2],
) -> (f64, f64) {
    let (at, len, per_mm) = anchor_measure(state, m, q);
    let mut w = Writer::new(out, nl, state).at(at);
    w.line("; poa: anchor the strand's end");
    w.extrude_to(q, len * per_mm);
    w.sync_e(state.e_logical());
    (len, len * per_mm)
}

/// Where an anchor to `q` starts (the nozzle where `state` says), its length, and the E per
/// mm of the move `m` it continues.
fn anchor_measure(state: &Machine, m: &crate::machine::Move, q: [f64; 2]) -> ([f64; 3], f64, f64) {
    let at = state.position();
    let len = (q[0] - at[0]).hypot(q[1] - at[1]);
    let per_mm = m.e / (m.to[0] - m.from[0]).hypot(m.to[1] - m.from[1]).max(1e-9);
    (at, len, per_mm)
}

/// Brings the nozzle from where it really is to where `state` says it is.
fn resync(
    out: &mut Vec<u8>,
    nl: &'static str,
    state: &Machine,
    real: &mut Option<[f64; 2]>,
    motion: &Motion,
) {
    let Some(from) = real.take() else {
        return;
    };
    let at = state.position();
    let d = ((at[0] - from[0]).powi(2) + (at[1] - from[1]).powi(2)).sqrt();
    if d < 1e-6 {
        return;
    }
    let mut w = Writer::new(out, nl, state).at([from[0], from[1], at[2]]);
    let t = &motion.travel;
    w.travel(
        t,
        [at[0], at[1]],
        d > t.short_travel && !state.is_retracted(),
    );
    w.feed_to(MmPerMin(state.feedrate()));
    w.sync_e(state.e_logical());
}

/// What is done to one G-code line of a slicer strand whose end would hang over air.
#[derive(Default)]
struct Tail {
    line: u64,
    /// Intervals (cumulative length along the move) cut away: an end nothing can hold and
    /// nothing printed after it leans on.
    cut: Vec<(f64, f64)>,
    /// Extrude from this point to the move's start first: the strand's start hung in air and
    /// is anchored on material close by.
    before: Option<[f64; 2]>,
    /// Extrude from the move's end on to this point: the same for the strand's end.
    after: Option<[f64; 2]>,
    /// The rewrite it lies beside.
    region: usize,
}

/// How far from a zone's box a sparse-infill end is "beside the region" (mm).
const TAIL_NEAR: f64 = 10.0;
/// Longest dangling end handled (mm): a longer one is not a stray end of a strand. The
/// last strand of a bridge PrusaSlicer anchors over sparse infill runs up to about 6 mm from
/// the perimeter it turned on to where it stops over a gap of the infill below.
const TAIL_MAX: f64 = 8.0;
/// Shortest dangling end handled (mm): shorter ones are one sample of the check.
const TAIL_MIN: f64 = 0.15;
/// Longest anchor drawn from a dangling end to material that holds it, in bead widths: the
/// slicer's infill ends stop about a width short of the walls, and the wall behind may be
/// the inner one.
const ANCHOR_WIDTHS: f64 = 4.0;

/// The slicer's infill ends beside the zones that would hang over air: on the first floating
/// layer the slicer cuts the column's infill where its bridge anchors begin, and the cut ends
/// lie over the gaps of the sparse infill below, held by nothing; the bridge infill kept
/// outside a zone ends over the same gaps (the deposition check's "in air"; 1.3-4.3 mm per
/// layer on test parts). Judged by the check's own model ([`crate::check::EndSupport`]): an
/// unsupported run at either end of a sparse-, solid- or bridge-infill path (a solid
/// infill's corners hang past each layer of a 60 degree slope),
/// up to [`TAIL_MAX`], is anchored (extended by at most [`ANCHOR_WIDTHS`] widths onto the nearest
/// material that holds it, the run then held at both ends like a short bridge); failing
/// that it is cut back to its first supported point, unless a strand printed after it on
/// this layer or on the layer `above` rests on it (no cut when the layer above is not known).
/// Paths with arcs, and moves in relative coordinates, are left as they are.
fn dangling_tails(
    layer: &Layer,
    below: &[&Layer],
    above: Option<&Layer>,
    zones: &[&MultiPolygon<f64>],
    boxes: &[Option<geo::Rect<f64>>],
    filament_area: f64,
) -> Vec<Tail> {
    let near: Vec<([f64; 2], [f64; 2], usize)> = boxes
        .iter()
        .enumerate()
        .filter_map(|(i, b)| {
            let b = (*b)?;
            Some((
                [b.min().x - TAIL_NEAR, b.min().y - TAIL_NEAR],
                [b.max().x + TAIL_NEAR, b.max().y + TAIL_NEAR],
                i,
            ))
        })
        .collect();
    if near.is_empty() {
        return Vec::new();
    }
    let inside = |q: [f64; 2], l: [f64; 2], h: [f64; 2]| {
        q[0] >= l[0] && q[0] <= h[0] && q[1] >= l[1] && q[1] <= h[1]
    };
    let boxes: Vec<([f64; 2], [f64; 2])> = near.iter().map(|(l, h, _)| (*l, *h)).collect();
    let mut sup = crate::check::EndSupport::new(below, &boxes, filament_area);
    let zone_boxes: Vec<Option<geo::Rect<f64>>> = zones
        .iter()
        .map(|z| geo::BoundingRect::bounding_rect(*z))
        .collect();
    let mut tails: Vec<Tail> = Vec::new();
    let entry = |tails: &mut Vec<Tail>, line: u64, region: usize| -> usize {
        match tails.iter().position(|t| t.line == line) {
            Some(i) => i,
            None => {
                tails.push(Tail {
                    line,
                    region,
                    ..Default::default()
                });
                tails.len() - 1
            }
        }
    };
    for (k, path) in layer.paths.iter().enumerate() {
        if !path
            .points
            .iter()
            .any(|q| boxes.iter().any(|(l, h)| inside(*q, *l, *h)))
        {
            continue;
        }
        let one_segment_per_line = path.seg_line.windows(2).all(|w| w[0] != w[1]);
        let n = path.seg_line.len();
        let loose = matches!(
            path.role,
            Role::Infill | Role::SolidInfill | Role::BridgeInfill | Role::InternalBridge
        );
        let dangling = (loose && one_segment_per_line && n > 0)
            .then(|| sup.dangling(path, TAIL_MAX))
            .flatten();
        if let Some((head, tail)) = dangling {
            let total = path.length();
            for (a, b, at_start) in [(0.0, head, true), (total - tail, total, false)] {
                if b - a < TAIL_MIN || b - a >= total - 1e-6 {
                    continue;
                }
                let mid = point_at(&path.points, (a + b) / 2.0);
                let Some(&(_, _, region)) = near.iter().find(|(l, h, _)| inside(mid, *l, *h))
                else {
                    continue;
                };
                let (seg, end, inner) = if at_start {
                    (0, path.points[0], path.points[1])
                } else {
                    (n - 1, path.points[n], path.points[n - 1])
                };
                let ahead = [end[0] - inner[0], end[1] - inner[1]];
                // An end in or at a zone is taken out or rests on the loops printed first.
                // (Zones whose box is farther are not measured: a plate's cap layer asked
                // every zone's every edge for every infill end.)
                let near_box = |b: &Option<geo::Rect<f64>>| {
                    b.is_none_or(|b| {
                        let r = path.width;
                        end[0] >= b.min().x - r
                            && end[0] <= b.max().x + r
                            && end[1] >= b.min().y - r
                            && end[1] <= b.max().y + r
                    })
                };
                if zones.iter().zip(&zone_boxes).any(|(z, b)| {
                    use geo::{Distance, Euclidean};
                    near_box(b)
                        && Euclidean.distance(*z, &geo::Point::new(end[0], end[1])) <= path.width
                }) {
                    continue;
                }
                if let Some(q) = sup.anchor(end, ahead, path.width, ANCHOR_WIDTHS * path.width) {
                    let i = entry(&mut tails, path.seg_line[seg], region);
                    if at_start {
                        tails[i].before = Some(q);
                    } else {
                        tails[i].after = Some(q);
                    }
                    continue;
                }
                // What the layer above rests on is known only when it was read: no cut
                // without it.
                let Some(above) = above else {
                    continue;
                };
                let run: Vec<[f64; 2]> = sub_polyline(&path.points, a, b);
                let later = layer.paths[k + 1..].iter().chain(above.paths.iter());
                if leaned_on(&run, path.width / 2.0, later) {
                    continue;
                }
                let mut s = 0.0;
                for (i, w) in path.points.windows(2).enumerate() {
                    let len = polyline_length(w);
                    let (x, y) = (a.max(s), b.min(s + len));
                    if y - x > 1e-9 {
                        let t = entry(&mut tails, path.seg_line[i], region);
                        tails[t].cut.push((x - s, y - s));
                    }
                    s += len;
                }
            }
        }
        sup.add(path);
    }
    tails.sort_by_key(|t| t.line);
    tails
}

/// Most points of the layer above's strands past a region's outline that [`overhung`]
/// buffers: a slope stepping out leaves a few strands' worth near a region.
const MAX_POKE_POINTS: usize = 20_000;

/// The part of `pts` between cumulative lengths `a` and `b`.
fn sub_polyline(pts: &[[f64; 2]], a: f64, b: f64) -> Vec<[f64; 2]> {
    let mut out = vec![point_at(pts, a)];
    let mut s = 0.0;
    for w in pts.windows(2) {
        s += polyline_length(w);
        if s > a && s < b {
            out.push(w[1]);
        }
    }
    out.push(point_at(pts, b));
    out
}

/// Whether a strand of `later` rests on the bead along `run` (half width `half`): one of its
/// points, sampled as the check samples, lies within the check's reach of it.
fn leaned_on<'a>(
    run: &[[f64; 2]],
    half: f64,
    mut later: impl Iterator<Item = &'a crate::layers::Path>,
) -> bool {
    let Some(b) = crate::geometry::points_box(run) else {
        return false;
    };
    let seg_dist = |p: [f64; 2], a: [f64; 2], c: [f64; 2]| {
        let (_, n) = crate::geometry::nearest_on_segment(p, a, c);
        (n[0] - p[0]).hypot(n[1] - p[1])
    };
    later.any(|p| {
        let reach = 0.25 * p.width;
        let m = half + reach + 0.1;
        p.points.windows(2).any(|w| {
            let (lo, hi) = (
                [w[0][0].min(w[1][0]), w[0][1].min(w[1][1])],
                [w[0][0].max(w[1][0]), w[0][1].max(w[1][1])],
            );
            if hi[0] < b.min().x - m
                || lo[0] > b.max().x + m
                || hi[1] < b.min().y - m
                || lo[1] > b.max().y + m
            {
                return false;
            }
            let len = polyline_length(w);
            let n = ((len / 0.1).ceil() as usize).clamp(1, 100_000);
            (0..n).any(|k| {
                let t = (k as f64 + 0.5) / n as f64;
                let q = [
                    w[0][0] + t * (w[1][0] - w[0][0]),
                    w[0][1] + t * (w[1][1] - w[0][1]),
                ];
                run.windows(2)
                    .any(|r| seg_dist(q, r[0], r[1]) - half <= reach)
            })
        })
    })
}

/// A gradual overhang's strands with their ends anchored: a moved perimeter (or the half
/// loop under it) that starts or ends past the layer below (where a sloped face meets a
/// vertical one) is extended by at most [`ANCHOR_WIDTHS`] widths onto the nearest material
/// of the layer below that holds it, as the slicer's infill ends are ([`dangling_tails`]).
/// `below` is the layer below as written (read back when poa rewrote it).
fn anchor_gradual(
    r: &RegionRewrite,
    layer: &Layer,
    below: &[&Layer],
    motion: &Motion,
    flow: f64,
) -> RegionRewrite {
    let mut r = r.clone();
    let Some(b) = geo::BoundingRect::bounding_rect(&r.plan.zone) else {
        return r;
    };
    let m = TAIL_NEAR;
    let area = [(
        [b.min().x - m, b.min().y - m],
        [b.max().x + m, b.max().y + m],
    )];
    let mut sup = crate::check::EndSupport::new(below, &area, motion.filament_area);
    // The block goes in where the slicer's external perimeter first comes near the zone:
    // what the layer printed before that (its inner perimeters, usually) holds it too.
    let near = |q: &[f64; 2]| {
        q[0] >= b.min().x - 1.0
            && q[0] <= b.max().x + 1.0
            && q[1] >= b.min().y - 1.0
            && q[1] <= b.max().y + 1.0
    };
    let block_line = layer
        .paths
        .iter()
        .filter(|p| matches!(p.role, Role::ExternalPerimeter | Role::OverhangPerimeter))
        .filter(|p| p.points.iter().any(near))
        .filter_map(|p| p.seg_line.first().copied())
        .min()
        .unwrap_or(0);
    for p in layer
        .paths
        .iter()
        .filter(|p| p.role == Role::Perimeter && p.seg_line.last().is_some_and(|&l| l < block_line))
    {
        sup.add(p);
    }
    let height = r.height;
    for s in &mut r.plan.strands {
        let n = s.points.len();
        // A closed ring has no end to hang.
        if n < 2 || polyline_length(&[s.points[0], s.points[n - 1]]) < 1e-9 {
            continue;
        }
        let per_mm = motion.e_per_mm(s.width, height, flow);
        let path = crate::layers::Path {
            role: Role::ExternalPerimeter,
            width: s.width,
            height,
            z: layer.z,
            object: None,
            tool: 0,
            points: s.points.clone(),
            seg_line: (0..n as u64 - 1).collect(),
            seg_e: s
                .points
                .windows(2)
                .map(|w| polyline_length(w) * per_mm)
                .collect(),
            feed: 0.0,
        };
        let dd = sup.dangling(&path, TAIL_MAX);
        let Some((head, tail)) = dd else {
            continue;
        };
        let reach = ANCHOR_WIDTHS * s.width;
        if tail >= TAIL_MIN {
            let (end, inner) = (s.points[n - 1], s.points[n - 2]);
            let ahead = [end[0] - inner[0], end[1] - inner[1]];
            if let Some(q) = sup.anchor(end, ahead, s.width, reach) {
                s.points.push(q);
            }
        }
        if head >= TAIL_MIN {
            let (end, inner) = (s.points[0], s.points[1]);
            let ahead = [end[0] - inner[0], end[1] - inner[1]];
            if let Some(q) = sup.anchor(end, ahead, s.width, reach) {
                s.points.insert(0, q);
            }
        }
    }
    r
}

/// Sorted intervals with overlapping ones joined.
fn merge_intervals(sorted: Vec<(f64, f64)>) -> Vec<(f64, f64)> {
    let mut out: Vec<(f64, f64)> = Vec::with_capacity(sorted.len());
    for (a, b) in sorted {
        match out.last_mut() {
            Some(last) if a <= last.1 => last.1 = last.1.max(b),
            _ => out.push((a, b)),
        }
    }
    out
}

/// Parameter intervals (in units of cumulative length along `pts`) of the polyline inside
/// `zone`, merged and sorted.
fn inside_intervals(pts: &[[f64; 2]], zone: &RingIndex) -> Vec<(f64, f64)> {
    let total = polyline_length(pts);
    if total <= 1e-9 {
        return Vec::new();
    }
    let iv: Vec<(f64, f64)> = zone
        .inside_intervals(pts)
        .into_iter()
        .filter(|(a, b)| b - a > 1e-4)
        .collect();
    // Pieces kept outside the zone shorter than this are slivers of the zone's edge: a bead
    // too short to print (its E rounds to nothing) that costs a travel on each side.
    let sliver = MIN_SEGMENT * 5.0;
    let mut merged: Vec<(f64, f64)> = Vec::new();
    for (a, b) in iv {
        match merged.last_mut() {
            Some(last) if a <= last.1 + sliver => last.1 = last.1.max(b),
            _ => merged.push((a, b)),
        }
    }
    if let Some(first) = merged.first_mut() {
        if first.0 < sliver {
            first.0 = 0.0;
        }
    }
    if let Some(last) = merged.last_mut() {
        if total - last.1 < sliver {
            last.1 = total;
        }
    }
    merged
}

/// The point at cumulative length `s` along `pts`, and the index of the segment holding it.
fn point_at(pts: &[[f64; 2]], s: f64) -> [f64; 2] {
    let mut acc = 0.0;
    for w in pts.windows(2) {
        let len = ((w[1][0] - w[0][0]).powi(2) + (w[1][1] - w[0][1]).powi(2)).sqrt();
        if acc + len >= s && len > 0.0 {
            let t = ((s - acc) / len).clamp(0.0, 1.0);
            return [
                w[0][0] + t * (w[1][0] - w[0][0]),
                w[0][1] + t * (w[1][1] - w[0][1]),
            ];
        }
        acc += len;
    }
    pts[pts.len() - 1]
}

/// Pieces of a path between cut points: (end point, length, inside a zone).
fn pieces(pts: &[[f64; 2]], inside: &[(f64, f64)]) -> Vec<([f64; 2], f64, bool)> {
    let total = polyline_length(pts);
    // Cut points, snapped to the ends so that no sliver piece is left at either end.
    let snap = |t: f64| {
        if t < 1e-4 {
            0.0
        } else if t > total - 1e-4 {
            total
        } else {
            t
        }
    };
    let mut cuts: Vec<(f64, bool)> = vec![(0.0, false)];
    for (a, b) in inside {
        cuts.push((snap(*a), true));
        cuts.push((snap(*b), false));
    }
    cuts.push((total, false));
    let mut vertex_s = Vec::with_capacity(pts.len());
    let mut acc = 0.0;
    vertex_s.push(0.0);
    for w in pts.windows(2) {
        acc += ((w[1][0] - w[0][0]).powi(2) + (w[1][1] - w[0][1]).powi(2)).sqrt();
        vertex_s.push(acc);
    }
    let mut out: Vec<([f64; 2], f64, bool)> = Vec::new();
    for c in cuts.windows(2) {
        let ((s0, ins), s1) = (c[0], c[1].0);
        if s1 - s0 <= 1e-6 {
            continue;
        }
        let mut prev = s0;
        let interior = vertex_s
            .iter()
            .zip(pts)
            .filter(|(v, _)| **v > s0 + 1e-6 && **v < s1 - 1e-6)
            .map(|(v, p)| (*v, *p));
        for (v, p) in interior.chain(std::iter::once((s1, point_at(pts, s1)))) {
            match out.last_mut() {
                // Consecutive travel pieces collapse into one move.
                Some(last) if ins && last.2 => {
                    last.0 = p;
                    last.1 += v - prev;
                }
                _ => out.push((p, v - prev, ins)),
            }
            prev = v;
        }
    }
    out
}

/// Replaces one extrusion line: outside the zones it extrudes its share of E along its own
/// path; inside, the nozzle stays put (`real` records where it is) so that runs of removed
/// extrusion collapse into one travel, made when the next extrusion or move needs it.
/// Returns the length and filament taken out.
#[allow(clippy::too_many_arguments)]
fn split_move(
    out: &mut Vec<u8>,
    nl: &'static str,
    real: &mut Option<[f64; 2]>,
    motion: &Motion,
    before: &Machine,
    m: &crate::machine::Move,
    pts: &[[f64; 2]],
    inside: &[(f64, f64)],
    original: &[u8],
    mut entry: Option<&mut EntryBlock>,
) -> (f64, f64) {
    let total = polyline_length(pts);
    let per_mm = m.e / total;
    let z = before.position()[2];
    let start = real.unwrap_or([m.from[0], m.from[1]]);
    let mut w = Writer::new(out, nl, before).at([start[0], start[1], z]);
    w.line(&format!(
        "; poa: split {}",
        String::from_utf8_lossy(original).trim()
    ));
    // Where the file believes the nozzle is, piece by piece.
    let mut file_pos = [m.from[0], m.from[1]];
    let mut removed = (0.0, 0.0);
    for (p, len, ins) in pieces(pts, inside) {
        if ins {
            if let Some(block) = entry.take() {
                // Written here, where the move enters the zone: the nozzle stays where the
                // block ends.
                let pen = w.pen();
                let state = before.partway([pen.pos[0], pen.pos[1]], pen.e, pen.feed.0);
                let end = block(out, &state);
                w = Writer::resume(
                    out,
                    nl,
                    crate::writer::Pen {
                        pos: [end[0], end[1], pen.pos[2]],
                        ..pen
                    },
                );
                *real = Some(end);
            }
            if real.is_none() {
                let p = w.position();
                *real = Some([p[0], p[1]]);
            }
            removed.0 += len;
            removed.1 += len * per_mm;
        } else {
            if real.take().is_some() {
                let d = dist(w.position(), file_pos);
                if d > 1e-6 {
                    w.travel(&motion.travel, file_pos, d > motion.travel.short_travel);
                }
            }
            w.feed_to(MmPerMin(m.feed));
            w.extrude_to(p, len * per_mm);
        }
        file_pos = p;
    }
    // The modal feedrate after this line is the line's own; back on the file's E count.
    w.feed_to(MmPerMin(m.feed));
    w.sync_e(before.e_logical() + m.e);
    removed
}

/// What writes the blocks that go where a rewritten move enters a zone, from the state
/// there; returns where the nozzle is left.
type EntryBlock<'a> = dyn FnMut(&mut Vec<u8>, &Machine) -> [f64; 2] + 'a;

/// Writes one region's strands, leaving the machine as `before` had it; with `exit`, a
/// gradual overhang's block written where the wall enters its zone, the nozzle is left where
/// the block ends, as near `exit` (where the wall leaves the zone) as the strands' order
/// allows. Returns where the nozzle is left.
///
/// Long by design: writes one region's block top to bottom (approach, fan and temperature, strands, restore) in print order, so that what is set and what is restored read side by side.
#[allow(clippy::too_many_arguments)]
fn emit_block(
    out: &mut Vec<u8>,
    nl: &'static str,
    before: &Machine,
    rewrite: &RegionRewrite,
    motion: &Motion,
    settings: &PoaSettings,
    tags: &Tags,
    stats: &mut RewriteStats,
    exit: Option<[f64; 2]>,
) -> [f64; 2] {
    let mut w = Writer::new(out, nl, before);
    let t = &motion.travel;
    let home = [before.position()[0], before.position()[1]];
    // Hops into and out of the block up to this long go without retraction and lift: the
    // file's own short travels, and for a gradual overhang's block (which starts and ends
    // beside the perimeter the slicer was printing, over the part) up to this layer's
    // features' size, where a retraction and Z-hop each way would cost more than the strand.
    let hop = if rewrite.plan.with_perimeter {
        t.short_travel.max(THIN_HOP)
    } else {
        t.short_travel
    };
    // A gradual overhang's strands start where the nozzle is (where the slicer's perimeter
    // did): no travel there and back for a block of one strand.
    let reordered;
    let plan = if rewrite.plan.with_perimeter {
        let from_home = crate::poa::reorder_from(&rewrite.plan.strands, home);
        // Written in place, the block may instead start at the far end of its ring and end
        // where the wall goes on (a loop and the perimeter back over it end where they
        // began): the hop in goes without retraction, the one out after the block with it.
        let strands = match exit {
            Some(x) => {
                let from_exit = crate::poa::reorder_from(&rewrite.plan.strands, x);
                let d2 = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).hypot(a[1] - b[1]);
                let cost = |s: &[Strand]| match (s.first(), s.last()) {
                    (Some(a), Some(b)) => match (a.points.first(), b.points.last()) {
                        // The hop out counts twice: it goes with retraction and lift.
                        (Some(&p), Some(&q)) => d2(home, p) + 2.0 * d2(q, x),
                        _ => f64::INFINITY,
                    },
                    _ => f64::INFINITY,
                };
                if cost(&from_exit) <= cost(&from_home) {
                    from_exit
                } else {
                    from_home
                }
            }
            None => from_home,
        };
        reordered = Plan {
            strands,
            ..rewrite.plan.clone()
        };
        &reordered
    } else {
        &rewrite.plan
    };
    w.line(&format!(
        ";POA_BEGIN region {} ({}): {} loops, {} strands",
        rewrite.id,
        rewrite.kind.name(),
        plan.loops,
        plan.strands.len()
    ));
    w.line(tags.loops_role());
    // A file that tags bead heights says the loops' own: after a thick bridge's
    // `;HEIGHT:0.39` in a 0.2 mm layer, a reader took them for beads half as wide.
    // (Only where the last tag says otherwise: most blocks follow a `;HEIGHT:` of the layer.)
    let tagged = tags.height.as_deref().and_then(|t| {
        t.strip_prefix(";HEIGHT:")
            .and_then(|v| v.trim().parse::<f64>().ok())
    });
    let height_tagged =
        tags.height.is_some() && tagged.is_none_or(|h| (h - rewrite.height).abs() > 1e-3);
    if height_tagged {
        w.line(&format!(";HEIGHT:{}", fmt_num(rewrite.height, 3)));
    }
    let was_retracted = before.is_retracted();
    // What the block pushes back at its start and pulls back at its end: the file's own
    // retraction, never more than any printer retracts (a wrong count must not push metres
    // of filament through the nozzle).
    let pulled = before.retracted.clamp(0.0, MAX_RETRACTION);
    let height = rewrite.height;
    let mut travel = 0.0;
    let mut time = 0.0;
    // Get to the first strand like the file travels.
    if let Some(first) = plan.strands.first() {
        if was_retracted {
            w.set_feed(t.travel_speed);
            travel += dist(w.position(), first.points[0]);
            w.move_to(first.points[0]);
            w.unretract(t, pulled);
        } else {
            // A short hop (a gradual overhang's block starts where the slicer's perimeter
            // was) goes without retraction, as the file's own short travels do.
            let d = dist(w.position(), first.points[0]);
            travel += w.travel(t, first.points[0], d > hop);
        }
    }
    // The setting is a percentage: written as a whole PWM step (90 % is S230).
    w.fan((settings.fan * 255.0).round() / 255.0, false);
    // A temperature change only when the file says what the temperature is.
    let temp = before
        .hotend_temp
        .filter(|t| *t > 0.0 && settings.temperature_offset != 0.0);
    if let Some(c) = temp {
        w.hotend(c + settings.temperature_offset);
    }
    let mut width_tag = f64::NAN;
    let mut last_loop = 0;
    // Each loop's length, for its cooling time.
    let mut loop_lengths: std::collections::HashMap<usize, f64> = Default::default();
    for s in plan.strands.iter().filter(|s| s.kind == StrandKind::Loop) {
        *loop_lengths.entry(s.loop_index).or_default() += s.length();
    }
    for (i, s) in plan.strands.iter().enumerate() {
        // The width the E makes, by the flow model at this layer's height.
        let per_mm = motion.e_per_mm(s.width, height, settings.flow_factor);
        if i > 0
            && connects(&plan.strands[i - 1], s)
            && !over_area(
                &rewrite.no_connect,
                [w.position()[0], w.position()[1]],
                s.points[0],
            )
        {
            // The next loop starts beside the end of this one: an extruded step over the
            // loop just laid, with no travel (short strokes across a narrow arm would
            // otherwise spend a fifth of their length on hops).
            let len = dist(w.position(), s.points[0]);
            let de = len * per_mm;
            w.extrude_to(s.points[0], de);
            stats.written_length_mm += len;
            stats.written_filament_mm += de;
            stats.connectors += 1;
            time += len / motion.loop_speed.0;
        } else if i > 0 {
            let d = dist(w.position(), s.points[0]);
            // Inside a gradual overhang's block too: its strands lie along the wall, over
            // the part, and a retraction and lift each way cost more than the strand. A hop
            // over the block's own fresh strands goes without them as well (the slicers'
            // combing: what oozes lands on a loop): strokes across a twisted bar's crescent,
            // each a few millimetres, had a retraction and a Z-hop each way between them.
            let short = d <= hop.max(2.0 * s.width)
                || (d <= OVER_LOOPS_HOP
                    && over_laid(
                        plan.strands[..i].iter().map(|s| &s.points[..]),
                        [w.position()[0], w.position()[1]],
                        s.points[0],
                        s.width,
                    ));
            let hop = w.travel(t, s.points[0], !short);
            travel += hop;
            stats.inner_travel_mm += hop;
            stats.longest_inner_travel_mm = stats.longest_inner_travel_mm.max(hop);
            time += t.travel_time(d);
        }
        if settings.dwell > 0.0
            && s.kind == StrandKind::Loop
            && s.loop_index != last_loop
            && last_loop > 0
        {
            w.dwell(settings.dwell);
            time += settings.dwell;
            stats.dwell_s += settings.dwell;
        }
        last_loop = s.loop_index;
        let bead = flow_width(per_mm, 1.0, height, motion.filament_area);
        if (bead - width_tag).abs() > 1e-6 {
            w.line(&tags.width_line(bead));
            width_tag = bead;
        }
        let speed = match s.kind {
            StrandKind::Perimeter => motion.perimeter_speed,
            // A gradual overhang's first ring lies mostly on the wall below, under the
            // slicer's perimeter, and leans on no loop of poa's: it goes at loop speed (the
            // cooling minimum doubled the time of a tilted ring's 60 short rings).
            StrandKind::Loop if rewrite.plan.with_perimeter && s.loop_index <= 1 => {
                motion.loop_speed
            }
            StrandKind::Loop => slowed_for_cooling(
                motion.loop_speed,
                loop_lengths.get(&s.loop_index).copied().unwrap_or(0.0),
                settings.min_loop_time,
                motion.cooling_floor,
            ),
            _ => motion.loop_speed,
        };
        w.set_feed(speed);
        write_strand(&mut w, s, per_mm, stats);
        time += s.length() / speed.0;
    }
    // Restore temperature, fan, position, retraction, feedrate, E counter and the slicer's tags.
    if let Some(c) = temp {
        w.hotend(c);
    }
    w.fan(before.fan, true);
    if exit.is_none() {
        travel += dist(w.position(), home);
        if was_retracted {
            w.retract(t, pulled);
            w.set_feed(t.travel_speed);
            w.move_to(home);
        } else {
            let d = dist(w.position(), home);
            w.travel(t, home, d > hop);
        }
    }
    time += t.travel_time(travel);
    if (w.position()[2] - before.position()[2]).abs() > 1e-9 {
        w.set_z(t, before.position()[2]);
    }
    w.restore_feed(MmPerMin(before.feedrate()));
    w.sync_e(before.e_logical());
    if let Some(tag) = &tags.role {
        w.line(tag);
    }
    if let Some(tag) = &tags.width {
        w.line(tag);
    }
    if let Some(tag) = tags.height.as_ref().filter(|_| height_tagged) {
        w.line(tag);
    }
    w.line(";POA_END");
    stats.travel_mm += travel;
    stats.time_added_s += time;
    let end = w.position();
    [end[0], end[1]]
}

/// Whether the loop strand `next` is reached from the end of `prev` by an extruded connector
/// instead of a travel: both are loops, `next` the same loop or the one after, it starts
/// within [`CONNECT_WIDTHS`] widths, the hop would be at least [`CONNECT_SHARE`] of its
/// length (short strokes across a narrow arm, small rings at a region's tip), and the
/// straight step between them stays on the two strands' beads (every point within
/// [`CONNECT_NEAR`] widths of one of them: a step across a gap or out of the region is
/// travelled).
fn connects(prev: &Strand, next: &Strand) -> bool {
    if prev.kind != StrandKind::Loop
        || next.kind != StrandKind::Loop
        || !(next.loop_index == prev.loop_index || next.loop_index == prev.loop_index + 1)
    {
        return false;
    }
    let (Some(&a), Some(&b)) = (prev.points.last(), next.points.first()) else {
        return false;
    };
    let w = prev.width.min(next.width);
    let len = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt();
    // A hop that is a small share of the strand it leads to is travelled: the connector,
    // laid round a corner off the fresh end of the loop before, is itself a short bridge.
    if len > CONNECT_WIDTHS * w || len < CONNECT_SHARE * polyline_length(&next.points) {
        return false;
    }
    over_laid([&prev.points[..], &next.points[..]], a, b, w)
}

/// Whether the step from `a` to `b` (its ends and middle) touches `area`.
fn over_area(area: &MultiPolygon<f64>, a: [f64; 2], b: [f64; 2]) -> bool {
    use geo::Intersects;
    !area.0.is_empty()
        && [a, [(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0], b]
            .iter()
            .any(|q| area.intersects(&geo::Point::new(q[0], q[1])))
}

/// Longest extruded connector between loops, in loop widths: the seam stagger of closed
/// rings (up to two widths along) and the step between strokes across a narrow arm.
const CONNECT_WIDTHS: f64 = 2.0;

/// How near (in widths) every point of a connector lies to one of the strands it joins: on
/// their beads as the check finds support (half a width plus its reach, a quarter).
const CONNECT_NEAR: f64 = 0.75;

/// Hops shorter than this share of the strand they lead to stay travels (long loops: the
/// travel is already a small part of the region's path).
const CONNECT_SHARE: f64 = 0.05;

/// Whether `p` lies within `r` of the polyline `line`.
fn near_polyline(p: [f64; 2], line: &[[f64; 2]], r: f64) -> bool {
    line.windows(2).any(|s| {
        let (_, c) = crate::geometry::nearest_on_segment(p, s[0], s[1]);
        (c[0] - p[0]).hypot(c[1] - p[1]) <= r
    })
}

/// How much more in air (mm) a rewritten layer may print than the slicer's before it is
/// sent out as sliced: the deposition check's own margin for "no worse" (at 0.5, layers above
/// gradual rewrites kept 0.3-0.5 mm more in air: a cup handle's, a star ledge's; at 0.3 over
/// 263 held-out slices, files with a layer worse than sliced 7 -> 2, in air 0.3-0.5 mm less).
const WORSE_IN_AIR: f64 = 0.3;

/// Length (mm) of a bridge's slicer strands the deposition check may find in air before
/// `--bridges auto` rewrites it: the acceptance's own mark for what a layer may keep in air.
const HANGING_BRIDGE: f64 = 1.0;

/// The box holding `boxes`, grown by `m` mm on every side; `None` for no box.
fn window_round(boxes: impl Iterator<Item = geo::Rect<f64>>, m: f64) -> Option<Window> {
    boxes
        .map(|b| {
            (
                [b.min().x - m, b.min().y - m],
                [b.max().x + m, b.max().y + m],
            )
        })
        .reduce(|a, b| {
            (
                [a.0[0].min(b.0[0]), a.0[1].min(b.0[1])],
                [a.1[0].max(b.1[0]), a.1[1].max(b.1[1])],
            )
        })
}

/// Regions smaller than this (mm2) are rewritten only where the deposition check finds the
/// slicer's strands over them in air (more than [`HANGING_BRIDGE`]), as `--bridges auto`
/// does for bridges: the arcs closing a small window in a thin wall, a narrow arm's gradual
/// strip (3-4 mm in air a layer) are; the many slivers whose perimeter the layer below
/// still holds are not (rewriting them made layers of a tilted ring 0.4 mm worse).
const SMALL_REGION: f64 = 1.0;

/// How far (mm) round the zones a rewritten layer is judged against the slicer's: the deposition
/// check's longest bridge ([`crate::check::CheckOptions::max_bridge`]'s default).
const JUDGE_REACH: f64 = 10.0;

/// Longest hop (mm) into or out of a gradual overhang's block made without retraction.
const THIN_HOP: f64 = 10.0;

/// Longest hop (mm) between a block's strands made without retraction and lift where it
/// runs over strands the block laid already ([`over_laid`]).
const OVER_LOOPS_HOP: f64 = 10.0;

/// Whether the straight step from `a` to `b` runs over the polylines `laid` (strands' centre
/// lines): every point of it (sampled every quarter of `width`) within [`CONNECT_NEAR`]
/// widths of one of them.
fn over_laid<'a>(
    laid: impl IntoIterator<Item = &'a [[f64; 2]]>,
    a: [f64; 2],
    b: [f64; 2],
    width: f64,
) -> bool {
    let len = (b[0] - a[0]).hypot(b[1] - a[1]);
    let r = CONNECT_NEAR * width;
    // Only strands whose box comes within reach of the hop's can hold a point of it.
    let (lo, hi) = (
        [a[0].min(b[0]) - r, a[1].min(b[1]) - r],
        [a[0].max(b[0]) + r, a[1].max(b[1]) + r],
    );
    let near: Vec<&[[f64; 2]]> = laid
        .into_iter()
        .filter(|p| {
            crate::geometry::points_box(p).is_some_and(|q| {
                q.min().x <= hi[0] && lo[0] <= q.max().x && q.min().y <= hi[1] && lo[1] <= q.max().y
            })
        })
        .collect();
    let n = ((len / (0.25 * width)).ceil() as usize).max(1);
    (0..=n).all(|k| {
        let t = k as f64 / n as f64;
        let p = [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])];
        near.iter().any(|line| near_polyline(p, line, r))
    })
}

/// Slowest speed poa slows a loop to for cooling unless told otherwise (`min_loop_speed`):
/// slower, the bead of a 0.4 mm nozzle no longer comes out even.
const COOLING_FLOOR: MmPerS = MmPerS(5.0);

/// The speed at which a loop of `length` mm takes at least `min_time` s, never above `speed`
/// nor below `floor`.
fn slowed_for_cooling(speed: MmPerS, length: f64, min_time: f64, floor: MmPerS) -> MmPerS {
    if min_time <= 0.0 || length <= 0.0 || length / speed.0 >= min_time {
        return speed;
    }
    MmPerS((length / min_time).max(floor.0).min(speed.0))
}

fn dist(a: [f64; 3], b: [f64; 2]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()
}

/// Vertices closer than this (mm) to the previous one are dropped: their E would round to a
/// bead of arbitrary width.
const MIN_SEGMENT: f64 = 0.02;

fn write_strand(w: &mut Writer<'_>, s: &Strand, per_mm: f64, stats: &mut RewriteStats) {
    let mut pts: Vec<[f64; 2]> = Vec::with_capacity(s.points.len());
    for p in &s.points {
        match pts.last() {
            Some(l) if ((p[0] - l[0]).powi(2) + (p[1] - l[1]).powi(2)).sqrt() < MIN_SEGMENT => {
                // Keep the strand's true end.
                if pts.len() > 1 {
                    if let Some(l) = pts.last_mut() {
                        *l = *p;
                    }
                }
            }
            _ => pts.push(*p),
        }
    }
    let mut prev = pts[0];
    for p in &pts[1..] {
        let len = ((p[0] - prev[0]).powi(2) + (p[1] - prev[1]).powi(2)).sqrt();
        if len < 1e-6 {
            continue;
        }
        let de = len * per_mm;
        w.extrude_to(*p, de);
        stats.written_length_mm += len;
        stats.written_filament_mm += de;
        prev = *p;
    }
}

/// The comment poa writes near the top of every file it rewrote; its presence means "done".
pub const HEADER_MARK: &str = "; poa print-on-air";

/// Whether `head` (the first bytes of a file) shows that poa already rewrote it: poa's header
/// line is line 2 of what it wrote, but lines may have been put before it since.
pub fn already_processed(head: &[u8]) -> bool {
    holds_header(head)
}

/// Whether any line of `text` is poa's header line.
fn holds_header(text: &[u8]) -> bool {
    let mark = HEADER_MARK.as_bytes();
    text.starts_with(mark) || memchr::memmem::find_iter(text, mark).any(|i| text[i - 1] == b'\n')
}

/// The error [`process`] stops with when it meets poa's header line past the head of the
/// file: the file was rewritten already, and nothing it wrote so far may be used.
pub fn already_processed_error() -> io::Error {
    io::Error::new(
        io::ErrorKind::AlreadyExists,
        "the file was already rewritten by poa",
    )
}

/// Whether `e` is [`already_processed_error`].
pub fn is_already_processed(e: &io::Error) -> bool {
    e.kind() == io::ErrorKind::AlreadyExists
}

/// What `process` did to a file.
#[derive(Debug, Clone, Default, Serialize)]
pub struct ProcessReport {
    /// The slicer that wrote the file, as detected.
    pub slicer: String,
    /// The objects the file labels, in order of appearance.
    pub objects: Vec<String>,
    pub regions_found: usize,
    pub regions_rewritten: usize,
    /// Regions left as the slicer made them, with the reason.
    pub skipped: Vec<SkippedRegion>,
    pub rewrites: Vec<RewriteStats>,
    pub loops: usize,
    /// Of the regions rewritten, gradual overhangs (their perimeter moved onto the layer
    /// below, see [`RewriteStats::gradual`]).
    pub gradual: usize,
    pub filament_added_mm: f64,
    pub filament_added_cm3: f64,
    pub filament_added_g: f64,
    pub time_added_s: f64,
    pub layers: usize,
    /// What poa assumed where the file is silent (a filament diameter read from the walls'
    /// E), one line each.
    pub notes: Vec<String>,
    /// Where in the output time was added, for the progress lines.
    #[serde(skip)]
    pub progress: Vec<crate::progress::Added>,
    /// Whether the file has `M73` progress lines.
    #[serde(skip)]
    pub has_progress_lines: bool,
}

#[derive(Debug, Clone, Serialize)]
pub struct SkippedRegion {
    pub region: usize,
    pub layer: usize,
    pub kind: RegionKind,
    pub reason: String,
}

/// The glob a pattern of [`ObjectFilter`] was made from.
fn glob_of(r: &regex::Regex) -> String {
    let re = r.as_str();
    let inner = re.strip_prefix('^').unwrap_or(re);
    let inner = inner.strip_suffix('$').unwrap_or(inner);
    let mut out = String::new();
    let mut chars = inner.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '.' if chars.peek() == Some(&'*') => {
                chars.next();
                out.push('*');
            }
            '.' => out.push('?'),
            '\\' => out.extend(chars.next()),
            c => out.push(c),
        }
    }
    out
}

/// Which objects to rewrite, by the names the file labels them with.
#[derive(Debug, Clone, Default)]
pub struct ObjectFilter {
    pub only: Vec<regex::Regex>,
    pub skip: Vec<regex::Regex>,
}

impl ObjectFilter {
    /// Builds a filter from comma-separated glob lists (`*` and `?` wildcards).
    pub fn from_globs(only: &[String], skip: &[String]) -> Result<Self, Error> {
        let conv = |g: &str| -> Result<regex::Regex, Error> {
            let mut re = String::from("^");
            for c in g.trim().chars() {
                match c {
                    '*' => re.push_str(".*"),
                    '?' => re.push('.'),
                    c => re.push_str(&regex::escape(&c.to_string())),
                }
            }
            re.push('$');
            regex::Regex::new(&re)
                .map_err(|e| Error::Invalid(format!("bad object pattern {g:?}: {e}")))
        };
        Ok(ObjectFilter {
            only: only.iter().map(|g| conv(g)).collect::<Result<_, _>>()?,
            skip: skip.iter().map(|g| conv(g)).collect::<Result<_, _>>()?,
        })
    }

    /// The patterns of `--objects` and `--skip-objects` that match none of `names`, as given.
    pub fn unmatched(&self, names: &[String]) -> Vec<String> {
        self.only
            .iter()
            .chain(&self.skip)
            .filter(|r| !names.iter().any(|n| r.is_match(n)))
            .map(glob_of)
            .collect()
    }

    pub fn allows(&self, name: Option<&str>) -> bool {
        let name = name.unwrap_or("");
        (self.only.is_empty() || self.only.iter().any(|r| r.is_match(name)))
            && !self.skip.iter().any(|r| r.is_match(name))
    }
}

/// Everything `process` needs besides the input.
pub struct ProcessOptions {
    pub detect: crate::geometry::DetectOptions,
    pub settings: PoaSettings,
    pub objects: ObjectFilter,
    /// The header comment's text (version and settings), written after the first line.
    pub header: String,
}

/// Print-on-Air as a pass: picks the regions the settings and object filters allow, plans
/// their loops on all cores, splices them into the layer and accounts filament and time.
pub struct PoaPass<'a> {
    opts: &'a ProcessOptions,
    motion: Motion,
    loop_width: f64,
    /// The file's settings state the external perimeter width (else the layer's own
    /// external perimeters tell it: CuraEngine writes no settings).
    width_stated: bool,
    /// Median external perimeter width of each of the last layers, where not stated.
    wall_widths: std::collections::VecDeque<f64>,
    /// The motion limits in force where each layer starts (the file changes them with M20x
    /// lines), for the time a rewrite adds.
    limits: crate::estimate::Estimator,
    /// Regions seen so far, for file-wide region numbers.
    next_id: usize,
    /// The last rewritten layer's index and its area as rewritten, which the layer above it
    /// is planned on.
    rewritten_below: Option<(usize, MultiPolygon<f64>)>,
    /// The area the layer being planned rests on, as rewritten, when it rests on the layer
    /// of [`PoaPass::rewritten_below`] and on others (support layers at their own heights
    /// in between): that layer as rewritten joined with the others as detected.
    joined_below: Option<(usize, MultiPolygon<f64>)>,
    /// The areas of the last few layers handed on, as detected (`None` where not made).
    recent_areas: std::collections::VecDeque<(usize, Option<MultiPolygon<f64>>)>,
    /// The last layer rewritten with wide regions only: what its area as rewritten is made
    /// of, made only if the layer above has regions of its own to plan on it.
    wide_below: Option<WideBelow>,
    /// The strands of the layer before the one being rewritten, as read (the deposition
    /// model that trims sparse-infill ends over air stands on them); see [`PoaPass::keep_below`].
    below_layers: std::collections::VecDeque<Layer>,
    /// The last layer this pass rewrote, read back from the bytes it wrote: what the layer
    /// above really stands on (moved perimeters, loops, cut and anchored ends).
    reread: Option<Layer>,
    /// The index of the layer [`PoaPass::keep_below`] kept as read back (the newest of
    /// `below_layers` then), if it did.
    kept_reread: Option<usize>,
    /// The layer rewritten without anchor strips by [`PoaPass::plan_best`] (its index, the
    /// rewrites' ids, bytes, statistics and read-back layer), which the rewrite then uses
    /// instead of writing it again.
    plain_written: Option<PlainWritten>,
    /// E extruded by the layers passed so far (the start G-code's priming left out).
    layers_e: f64,
    config: SlicerConfig,
    /// What the pass did so far.
    pub report: ProcessReport,
}

impl<'a> PoaPass<'a> {
    pub fn new(config: &SlicerConfig, opts: &'a ProcessOptions) -> Self {
        PoaPass {
            opts,
            motion: Motion::from_config(config, &opts.settings),
            loop_width: config.external_perimeter_width(),
            width_stated: config.external_perimeter_width_stated(),
            wall_widths: std::collections::VecDeque::new(),
            limits: crate::estimate::Estimator::new(crate::estimate::Limits::from_config(config)),
            next_id: 0,
            rewritten_below: None,
            joined_below: None,
            recent_areas: std::collections::VecDeque::new(),
            wide_below: None,
            below_layers: std::collections::VecDeque::new(),
            reread: None,
            kept_reread: None,
            plain_written: None,
            layers_e: 0.0,
            config: config.clone(),
            report: ProcessReport::default(),
        }
    }

    /// Width of the loops and the moved perimeter: the file's external perimeter width, or
    /// where the file does not state it (CuraEngine writes no settings), the median of the
    /// recent layers' external perimeter widths as extruded. Cura's 0.5 mm walls were taken
    /// for 0.45 mm, and the moved perimeter hung the difference farther out; a floating
    /// layer's own walls are no guide (Cura's bridge walls run at another flow).
    fn width_on(&self, layer: &Layer) -> f64 {
        if self.width_stated {
            return self.loop_width;
        }
        let mut seen: Vec<f64> = self.wall_widths.iter().copied().collect();
        if seen.is_empty() {
            seen.extend(median_wall_width(layer));
        }
        if seen.is_empty() {
            return self.loop_width;
        }
        let mid = seen.len() / 2;
        let (_, median, _) = seen.select_nth_unstable_by(mid, f64::total_cmp);
        // A width far from the nozzle's is a misread flow, not a wall.
        median.clamp(0.6 * self.loop_width, 2.0 * self.loop_width)
    }

    /// Notes the layer's external perimeter width for [`PoaPass::width_on`]. Not a first
    /// layer's: slicers print it wider (PrusaSlicer's default 200 %, 0.7 mm for 0.45 mm
    /// walls), and the median of it and the second layer's was the first layer's width:
    /// the second and third layers' gradual overhangs were planned with a perimeter pulled
    /// in by 0.35 mm instead of 0.225, off their thin ring (a hull's stern by PrusaSlicer's
    /// defaults: its perimeter left 0.17 mm past the first layer's edge, 39 mm in air).
    /// After [`PoaPass::layer_under`] panicked on `layer`: the layer goes out as sliced, what
    /// was kept for the layer above is dropped (the layer above is judged on the layer as
    /// sliced), and the report says so.
    pub fn left_as_sliced_after_panic(&mut self, layer: &Layer) {
        self.rewritten_below = None;
        self.joined_below = None;
        self.reread = None;
        self.wide_below = None;
        self.plain_written = None;
        self.report.notes.push(format!(
            "layer {} left as sliced: rewriting it failed inside poa (a panic, most likely in \
             the polygon library); please report it with the file",
            layer.index + 1
        ));
        self.limits.track_limits(&layer.raw);
        self.note_wall_width(layer);
    }

    fn note_wall_width(&mut self, layer: &Layer) {
        if self.width_stated || layer.kind != crate::layers::LayerKind::Layer || layer.on_bed() {
            return;
        }
        if let Some(w) = median_wall_width(layer) {
            if self.wall_widths.len() >= WALL_WIDTH_LAYERS {
                self.wall_widths.pop_front();
            }
            self.wall_widths.push_back(w);
        }
    }

    /// Numbers the layer's regions and picks those the settings and object filters allow;
    /// the others go to the report with the reason.
    fn choose<'r>(
        &mut self,
        d: &crate::geometry::Detected,
        regions: &'r [crate::geometry::Region],
        above_rewrite: bool,
        hanging: &[bool],
    ) -> (Chosen<'r>, Chosen<'r>) {
        let mut chosen = Vec::new();
        let mut left = Vec::new();
        for (k, r) in regions.iter().enumerate() {
            self.next_id += 1;
            self.report.regions_found += 1;
            let object = self.object_name(r.object);
            let report = &mut self.report;
            // Above a rewrite, a "bridge" is the gap a moved perimeter left: rewritten too.
            let hangs = hanging.get(k).copied().unwrap_or(false);
            let why = if d.layer.helical {
                "spiral layer (Z rises while it extrudes): its strands have no one height to write loops at"
            } else if r.max_distance > MAX_REACH {
                "reaches farther from what the layer below printed than any printer's part (a damaged file?)"
            } else if r.area < SMALL_REGION && !above_rewrite && !hangs {
                "small (under 1 mm2), and the slicer's strands over it are held"
            } else if !self.opts.settings.rewrites(r.kind) && !above_rewrite && !hangs {
                match r.kind {
                    RegionKind::Bridge => "bridge (use --bridges poa to rewrite bridges)",
                    _ => "floating: nothing below to grow loops from",
                }
            } else if !self.opts.objects.allows(object.as_deref()) {
                "object excluded by --objects/--skip-objects"
            } else {
                chosen.push((self.next_id, r));
                continue;
            };
            report.skipped.push(SkippedRegion {
                region: self.next_id,
                layer: d.layer.index + 1,
                kind: r.kind,
                reason: why.to_string(),
            });
            left.push((self.next_id, r));
        }
        (chosen, left)
    }

    /// For each of `regions`, whether it is a bridge that `--bridges auto` rewrites, or a
    /// region under [`SMALL_REGION`] that is rewritten: the deposition check finds more than
    /// [`HANGING_BRIDGE`] mm of the slicer's strands over it in air (spans longer than the check's longest bridge, strands along a gap instead
    /// of across it: a stair of fins by Cura, 75 mm in air on each gap's first layer).
    fn hanging(&self, layer: &Layer, regions: &[crate::geometry::Region]) -> Vec<bool> {
        use geo::Contains;
        let auto = |r: &crate::geometry::Region| {
            (r.kind == RegionKind::Bridge && self.opts.settings.bridges == BridgeMode::Auto)
                || r.area < SMALL_REGION
        };
        if !regions.iter().any(auto) {
            return vec![false; regions.len()];
        }
        let below = judged_on(&self.below_layers, layer);
        if below.is_empty() {
            return vec![false; regions.len()];
        }
        // With bridges to judge, the whole layer (a bridge's strands run far past it); with
        // small regions only, the strands round them (a plate's layer costs as much to check
        // as to search).
        use geo::BoundingRect;
        let m = JUDGE_REACH;
        let bridges = regions.iter().any(|r| {
            r.kind == RegionKind::Bridge && self.opts.settings.bridges == BridgeMode::Auto
        });
        let window = window_round(
            regions
                .iter()
                .filter(|r| auto(r))
                .filter_map(|r| r.polygon.bounding_rect()),
            m,
        );
        let fa = self.motion.filament_area;
        let c = match window.filter(|_| !bridges) {
            Some(w) => crate::check::check_layer_within(&below, layer, fa, w),
            None => crate::check::check_layer_samples(&below, layer, fa),
        };
        let in_air: Vec<&crate::check::Sample> = c
            .samples
            .iter()
            .filter(|s| s.support == crate::check::Support::InAir)
            .collect();
        let half = self.width_on(layer) / 2.0;
        regions
            .iter()
            .map(|r| {
                if !auto(r) || in_air.is_empty() {
                    return false;
                }
                // A strand's samples lie on its centreline, up to half a width past the
                // region's edge.
                let grown =
                    crate::geometry::offset(&MultiPolygon::new(vec![r.polygon.clone()]), half);
                let air: f64 = in_air
                    .iter()
                    .filter(|s| grown.contains(&geo::Point::new(s.point[0], s.point[1])))
                    .map(|s| s.length)
                    .sum();
                air > HANGING_BRIDGE
            })
            .collect()
    }

    /// `Some((as sliced, as rewritten))` in-air lengths (mm) when the deposition check finds
    /// the layer as rewritten (`back`) more than [`WORSE_IN_AIR`] mm farther in air than as
    /// sliced, over the layers it rests on as printed. `sliced` is the window the layer was
    /// checked in as sliced, and that check.
    ///
    /// Only near the regions: a plate-wide layer costs as much to judge as its region search.
    /// The window is the box round the planned zones grown by the longest bridge the check
    /// counts: the slicer's strands cut at a zone's edge (or trimmed back to what holds them)
    /// lie beside it, and a run of theirs that lost the end it was bridged to is in air now
    /// (an embossed letter's skin line, 4 mm from a 1 mm2 region's zone: 0 -> 1.2 mm in air on
    /// the layer, unjudged). Paths meeting the window are judged whole, and those away from
    /// every zone are the same in both layers, so a window round zones dropped since adds the
    /// same length to both sides.
    fn worse_in_air(
        &self,
        below: &[&Layer],
        back: &Layer,
        sliced: Option<(Window, &crate::check::LayerCheck)>,
    ) -> Option<(f64, f64)> {
        if below.is_empty() {
            return None;
        }
        let (window, sliced) = sliced?;
        let fa = self.motion.filament_area;
        let after = crate::check::in_air_within(below, back, fa, window);
        let before = sliced.in_air_mm;
        (after > before + WORSE_IN_AIR).then_some((before, after))
    }

    /// The name of object number `o`, as the file labels it.
    fn object_name(&self, o: Option<u32>) -> Option<String> {
        o.and_then(|o| self.report.objects.get(o as usize).cloned())
    }

    /// The area `layer` rests on as rewritten, when it rests on the layer of
    /// [`PoaPass::rewritten_below`] and on others, and is not the layer just after it
    /// printed on it alone (read as before): that layer as rewritten joined with the others'
    /// areas as detected; `None` when one of those is no longer kept.
    fn join_below(&self, layer: &Layer) -> Option<MultiPolygon<f64>> {
        let (i, rewritten) = self.rewritten_below.as_ref()?;
        if !layer.rests_on.contains(i) || (i + 1 == layer.index && layer.over_previous()) {
            return None;
        }
        let mut joined = rewritten.clone();
        for j in layer.rests_on.iter().filter(|j| *j != i) {
            let made;
            let area = match self.recent_areas.iter().find(|(k, _)| k == j) {
                Some((_, Some(a))) => a,
                // Not made by detection (a layer proven supported, the first layer): made
                // from the layer as kept, as detection would have.
                _ => {
                    let kept = self
                        .below_layers
                        .iter()
                        .find(|b| b.index == *j && b.kind == layer.kind)?;
                    made = crate::geometry::printed_area(kept, &self.opts.detect.area);
                    &made
                }
            };
            joined = crate::geometry::union(&joined, area);
        }
        Some(joined)
    }

    /// Keeps a layer's area as detected for [`PoaPass::join_below`].
    pub fn note_area(&mut self, index: usize, area: Option<MultiPolygon<f64>>) {
        if self.recent_areas.len() > ABOVE_AHEAD {
            self.recent_areas.pop_front();
        }
        self.recent_areas.push_back((index, area));
    }

    /// Hands the pass the layer just passed (its raw bytes may be gone): the next layer's
    /// rewrite judges the slicer's strand ends against it. A driver that does not call this
    /// gets no end trimming.
    pub fn keep_below(&mut self, layer: Layer) {
        if layer.kind == crate::layers::LayerKind::Layer {
            self.layers_e += layer.paths.iter().map(|p| p.e()).sum::<f64>();
        }
        self.kept_reread = None;
        let mut kept = match self.reread.take() {
            Some(r) if r.index == layer.index => {
                self.kept_reread = Some(r.index);
                r
            }
            _ => layer,
        };
        // Only the strands are judged against.
        kept.raw = Vec::new();
        kept.start = None;
        // A layer rests on the one before it, or where objects or support at other layer
        // heights interleave, on a few before that.
        if self.below_layers.len() >= KEEP_BELOW {
            self.below_layers.pop_front();
        }
        self.below_layers.push_back(kept);
    }

    /// [`PoaPass::plan`], with the slicer's bridge anchors over sparse infill planned with
    /// their regions ([`anchor_strips`]) where they hang as sliced and still hang in the
    /// layer rewritten without them, and the layer rewritten with them prints less in air
    /// round them (loops in a strip can leave the part's own infill ends beside it in air: a
    /// star's cap on its post, 0.1 -> 4.3 mm).
    fn plan_best(
        &mut self,
        d: &crate::geometry::Detected,
        area: &MultiPolygon<f64>,
        left: &Chosen<'_>,
        chosen: &Chosen<'_>,
        above: Option<&Layer>,
        above_regions: &[crate::geometry::Region],
    ) -> Vec<RegionRewrite> {
        let layer = &d.layer;
        self.plain_written = None;
        let above = above.filter(|a| a.rests_on.contains(&layer.index));
        // Where the layer above stands past each region's outline: made once for the three
        // plans below.
        let overhung: Option<Vec<MultiPolygon<f64>>> = above.map(|a| {
            use rayon::prelude::*;
            let widths = crate::poa::Widths {
                loop_width: self.width_on(layer),
                perimeter_width: self.width_on(layer),
                tolerance: self.opts.detect.tolerance_at(layer.height),
            };
            // One index of the layer's outline for all its regions (a plate of many small
            // regions beside one big body would index that body once per region).
            let outline = RingIndex::new(area);
            chosen
                .par_iter()
                .map(|(_, r)| overhung(a, above_regions, &outline, r, &widths))
                .collect()
        });
        let next = overhung.as_deref();
        let plain = |me: &mut Self| {
            me.plan(d, area, left, chosen, None, next)
                .unwrap_or_default()
        };
        // No strip where the slicer's anchors hold as sliced (a probe: nothing planned).
        if self
            .plan(d, area, left, chosen, Some((layer, true)), next)
            .is_none()
        {
            return plain(self);
        }
        // The layer rewritten without strips, read back: the slicer's anchor ends beside a
        // region are anchored or cut there ([`dangling_tails`]), and a strip is planned only
        // where they still hang.
        let skipped_at = self.report.skipped.len();
        let without = plain(self);
        let skipped_without = self.report.skipped.split_off(skipped_at);
        let keep_without = |me: &mut Self, without: Vec<RegionRewrite>| {
            me.report.skipped.truncate(skipped_at);
            me.report.skipped.extend(skipped_without.iter().cloned());
            without
        };
        let written = |me: &Self, rewrites: &[RegionRewrite]| {
            let below = resting_on(&me.below_layers, layer);
            let (bytes, stats) = rewrite_layer(
                layer,
                &below,
                above,
                rewrites,
                &me.motion,
                &me.opts.settings,
                BlockPlace::AtEntry,
            );
            let back = reread(layer, &bytes, &me.config);
            (bytes, stats, back)
        };
        let (bytes, stats, back) = written(self, &without);
        let ids: Vec<usize> = without.iter().map(|r| r.id).collect();
        let Some(back) = back else {
            return keep_without(self, without);
        };
        let with = match self.plan(d, area, left, chosen, Some((&back, false)), next) {
            Some(w) if w.iter().any(|r| !r.no_connect.0.is_empty()) => w,
            _ => {
                self.plain_written = Some((layer.index, ids, bytes, stats, Some(back)));
                return keep_without(self, without);
            }
        };
        // Judged round the strips only (the rest of the regions' loops are alike): their
        // cavities' boxes grown by a few millimetres, which hold the part's infill ends
        // beside a strip.
        let windows: Vec<Window> = with
            .iter()
            .filter_map(|r| geo::BoundingRect::bounding_rect(&r.no_connect))
            .map(|b| {
                (
                    [b.min().x - STRIP_JUDGED, b.min().y - STRIP_JUDGED],
                    [b.max().x + STRIP_JUDGED, b.max().y + STRIP_JUDGED],
                )
            })
            .collect();
        let in_air = |me: &Self, back: &Layer| -> f64 {
            let below = judged_on(&me.below_layers, layer);
            crate::check::samples_inside(&below, back, me.motion.filament_area, &windows)
                .iter()
                .filter(|s| s.support == crate::check::Support::InAir)
                .map(|s| s.length)
                .sum()
        };
        let a = written(self, &with)
            .2
            .map_or(f64::INFINITY, |b| in_air(self, &b));
        let b = in_air(self, &back);
        if a + STRIP_GAIN <= b {
            with
        } else {
            self.plain_written = Some((layer.index, ids, bytes, stats, Some(back)));
            keep_without(self, without)
        }
    }

    /// Whether a region no plan fits is held as sliced all the same: none of the layer's
    /// strands near it is in air by the deposition check over the layers below as they are
    /// written. (A gradual overhang's last region, over a perimeter moved in on the layer
    /// below, is found because the slicer's perimeter stands past that moved one by more than
    /// the tolerance, but still rests on it: reported as "no loop fits", 18 of a plate of
    /// nine lying cylinders read as left in air.)
    fn held_as_sliced(&self, layer: &Layer, region: &crate::geometry::Region, w: f64) -> bool {
        let below = judged_on(&self.below_layers, layer);
        let Some(b) = geo::BoundingRect::bounding_rect(&region.polygon) else {
            return false;
        };
        if below.is_empty() {
            return false;
        }
        let window = (
            [b.min().x - w, b.min().y - w],
            [b.max().x + w, b.max().y + w],
        );
        // The strands near it judged whole, as `poa check` judges them (a run leaving the
        // window is not taken as anchored at its edge).
        crate::check::check_layer_within(&below, layer, self.motion.filament_area, window)
            .samples
            .iter()
            .filter(|s| crate::check::inside_box(s.point, window))
            .all(|s| s.support != crate::check::Support::InAir)
    }

    /// Plans the chosen regions on all cores; regions where no loop fits go to the report.
    /// `strips: Some((judged, probe))`: the slicer's bridge anchors over sparse infill beside
    /// a region are planned with it where `judged` (the layer as sliced, or as rewritten
    /// without them) leaves them in air; a probe only says whether any would be (`None`: none;
    /// `Some` and empty: some), planning nothing ([`anchor_strips`]). `None` only for a probe.
    /// Strips asked for and none needed: `Some` and empty, planning nothing.
    fn plan(
        &mut self,
        d: &crate::geometry::Detected,
        area: &MultiPolygon<f64>,
        left: &Chosen<'_>,
        chosen: &Chosen<'_>,
        strips: Option<(&Layer, bool)>,
        overhung: Option<&[MultiPolygon<f64>]>,
    ) -> Option<Vec<RegionRewrite>> {
        let layer = &d.layer;
        let start = layer
            .start
            .as_ref()
            .map(|m| [m.position()[0], m.position()[1]])
            .unwrap_or([0.0, 0.0]);
        let widths = crate::poa::Widths {
            loop_width: self.width_on(layer),
            perimeter_width: self.width_on(layer),
            tolerance: self.opts.detect.tolerance_at(layer.height),
        };
        let settings = &self.opts.settings;
        // Over a layer rewritten with wide regions, the loops grow from what it prints as
        // rewritten (its perimeter pulled in by the inset, the loops out to it), while the
        // regions stay those found on it as sliced: an elbow's third layer, outer wall
        // first, grew from the slicer's perimeter below and hung past the moved one.
        let over_wide = self
            .wide_below
            .as_ref()
            .filter(|wb| wb.index + 1 == layer.index && layer.over_previous())
            .map(|wb| {
                // Made near the chosen regions only (the planner reads nothing farther): a
                // plate's worth of loops costs as much to buffer as the region search.
                let boxes: Vec<[f64; 4]> = chosen
                    .iter()
                    .filter_map(|(_, r)| {
                        let b = geo::BoundingRect::bounding_rect(&r.polygon)?;
                        let m = r.max_distance.min(1000.0)
                            + widths.tolerance
                            + 3.0 * widths.loop_width
                            + 1.0;
                        Some([b.min().x - m, b.min().y - m, b.max().x + m, b.max().y + m])
                    })
                    .collect();
                let near = |pts: &[[f64; 2]]| {
                    crate::geometry::points_box(pts).is_some_and(|b| {
                        boxes.iter().any(|w| {
                            b.min().x <= w[2]
                                && w[0] <= b.max().x
                                && b.min().y <= w[3]
                                && w[1] <= b.max().y
                        })
                    })
                };
                let window = boxes.iter().fold(MultiPolygon(Vec::new()), |acc, w| {
                    let rect = geo::Rect::new((w[0], w[1]), (w[2], w[3])).to_polygon();
                    crate::geometry::union(&acc, &MultiPolygon::new(vec![rect]))
                });
                let strands = wb
                    .strands
                    .iter()
                    .filter(|(p, _)| near(p))
                    .map(|(p, w)| (&p[..], *w));
                let rewritten = crate::geometry::rewritten_area(
                    &crate::geometry::intersection(&wb.area, &window),
                    &crate::geometry::intersection(&wb.zones, &window),
                    strands,
                );
                // The layer below as read back went to `below_layers` when it was passed.
                let back = self
                    .below_layers
                    .back()
                    .filter(|r| r.index == wb.index && self.kept_reread == Some(wb.index));
                match back {
                    Some(r) => {
                        let local = Layer {
                            paths: r
                                .paths
                                .iter()
                                .filter(|p| near(&p.points))
                                .cloned()
                                .collect(),
                            raw: Vec::new(),
                            start: None,
                            objects: None,
                            rests_on: r.rests_on.clone(),
                            contact: r.contact.clone(),
                            gap_below: r.gap_below.clone(),
                            helical: r.helical,
                            ..*r
                        };
                        let printed = crate::geometry::printed_area(&local, &self.opts.detect.area);
                        crate::geometry::intersection(
                            &rewritten,
                            &crate::geometry::offset(&printed, REREAD_SLACK),
                        )
                    }
                    None => rewritten,
                }
            });
        let below = match (&self.rewritten_below, &over_wide) {
            // A layer also resting on older layers through its taller beads (combined infill) grows
            // from the layer before as rewritten all the same: its walls stand on that one (a
            // 67-degree ledge, one wall, infill every other layer: every second layer's loops
            // grew from the perimeter as sliced below, 19.4 mm in air each).
            (Some((i, area)), _) if i + 1 == layer.index && layer.over_previous() => area,
            (_, Some(area)) => area,
            // Resting on that layer and on others (support layers at their own heights):
            // all of them, that one as rewritten.
            _ if self
                .joined_below
                .as_ref()
                .is_some_and(|(k, _)| *k == layer.index) =>
            {
                self.joined_below
                    .as_ref()
                    .map_or(&crate::geometry::NO_AREA, |(_, a)| a)
            }
            // A layer with regions of its own always has the area below.
            _ => d.below.as_ref().unwrap_or(&crate::geometry::NO_AREA),
        };
        // On the first layer, regions were found against it grown by the elephant-foot
        // compensation (the outline it squashes out to); loops grow from what it prints
        // (an elbow by PrusaSlicer: loop 1 laid 0.23 mm past the first layer's edge, 60 mm
        // in air by the deposition check).
        let shrink = self.opts.detect.first_layer_shrink;
        let printed_below;
        let below = if shrink > 0.0
            && d.below.as_ref().is_some_and(|b| std::ptr::eq(b, below))
            && self
                .below_layers
                .iter()
                .any(|b| b.on_bed() && layer.rests_on.contains(&b.index))
        {
            printed_below = crate::geometry::offset(below, -shrink);
            &printed_below
        } else {
            below
        };
        // A floating region within a bead of a rewritten one (walls round a slot in it), or
        // of a floating region planned with it (thick bridges' rings, each an island of its
        // own: the outermost left as sliced hung past the loops), is planned with it; the
        // regions left as sliced keep their strands.
        let mut absorbed: Vec<(usize, usize)> = Vec::new();
        let others: Vec<crate::poa::Others> = chosen
            .iter()
            .enumerate()
            .map(|(k, (id, r))| {
                use geo::Intersects;
                let grow = |p: &geo::Polygon<f64>| {
                    crate::geometry::offset(&MultiPolygon::new(vec![p.clone()]), widths.loop_width)
                };
                // The floating regions that may join. The grown outlines are made only when
                // one exists: growing a region's outline (thousands of round-join points
                // after the opening) cost as much as planning its loops, for nothing on
                // most layers.
                let candidate: Vec<bool> = left
                    .iter()
                    .map(|(_, f)| {
                        f.kind == RegionKind::Floating
                            && self
                                .opts
                                .objects
                                .allows(self.object_name(f.object).as_deref())
                    })
                    .collect();
                // Joining starts from the region: with no candidate's box within a loop width
                // of its box, none joins.
                let reach = |f: &geo::Polygon<f64>| {
                    use geo::BoundingRect;
                    let (Some(a), Some(b)) = (r.polygon.bounding_rect(), f.bounding_rect()) else {
                        return false;
                    };
                    let m = widths.loop_width + 1e-3;
                    a.min().x - m <= b.max().x
                        && b.min().x <= a.max().x + m
                        && a.min().y - m <= b.max().y
                        && b.min().y <= a.max().y + m
                };
                let mut near = Vec::new();
                if candidate
                    .iter()
                    .zip(left.iter())
                    .any(|(&c, (_, f))| c && reach(&f.polygon))
                {
                    near.push(grow(&r.polygon));
                }
                let mut joined = vec![false; left.len()];
                // Each pass joins the floating regions next to what is joined so far.
                while !near.is_empty() {
                    let mut grew = false;
                    for (k, (_, f)) in left.iter().enumerate() {
                        let joins = !joined[k]
                            && candidate[k]
                            && near.iter().any(|n| n.intersects(&f.polygon));
                        if joins {
                            joined[k] = true;
                            near.push(grow(&f.polygon));
                            grew = true;
                        }
                    }
                    if !grew {
                        break;
                    }
                }
                let mut o = crate::poa::Others::default();
                for ((fid, f), joined) in left.iter().zip(joined) {
                    if joined {
                        o.absorb.0.push(f.polygon.clone());
                        absorbed.push((*fid, *id));
                    } else {
                        o.keep_out.0.push(f.polygon.clone());
                    }
                }
                if let Some(v) = overhung.and_then(|v| v.get(k)) {
                    o.overhung = v.clone();
                }
                o
            })
            .collect();
        for (fid, id) in absorbed {
            if let Some(s) = self.report.skipped.iter_mut().find(|s| s.region == fid) {
                s.reason = format!("floating: planned with region {id}, beside it");
            }
        }
        // The slicer's bridge anchored over the sparse infill beside a region: its strands
        // there are planned with the region (see [`anchor_strips`]).
        let resting = resting_on(&self.below_layers, layer);
        let under = resting
            .last()
            .filter(|b| strips.is_some() && b.index + 1 == layer.index);
        // Copies of a part get their representative's strips, moved: made for each, their
        // booleans' noise differs and each copy's plan was made on its own (a plate of nine
        // mushrooms: nine plans instead of one).
        let sources = under.map(|_| {
            let plain: Vec<(&crate::geometry::Region, &crate::poa::Others)> =
                chosen.iter().map(|(_, r)| *r).zip(others.iter()).collect();
            crate::poa::copy_sources(&plain, below, area, widths)
        });
        let asked = strips.is_some();
        let (judged, probe) = strips.unwrap_or((layer, false));
        let strips = under
            .zip(sources.as_ref())
            .map(|(b, sources)| {
                anchor_strips(
                    (layer, judged),
                    (b, &resting),
                    below,
                    (chosen, sources),
                    widths.loop_width,
                    self.motion.filament_area,
                )
            })
            .unwrap_or_else(|| vec![None; chosen.len()]);
        if probe {
            return strips.iter().any(|s| s.is_some()).then(Vec::new);
        }
        // Strips asked for and none needed: the plan would be the plain one, which the caller
        // has made already (a plate of nine mushrooms planned its layer three times).
        if asked && strips.iter().all(|s| s.is_none()) {
            return Some(Vec::new());
        }
        let (extended, below_strips, area_strips);
        type Jobs<'j> = Vec<(&'j crate::geometry::Region, &'j crate::poa::Others)>;
        let (jobs, below, area): (Jobs<'_>, _, _) = if strips.iter().all(|s| s.is_none()) {
            (
                chosen.iter().map(|(_, r)| *r).zip(others.iter()).collect(),
                below,
                area,
            )
        } else {
            let cavities: Vec<&MultiPolygon<f64>> =
                strips.iter().flatten().map(|(_, c, _)| c).collect();
            let cavities = crate::geometry::union_all(&cavities);
            below_strips = crate::geometry::difference(below, &cavities);
            let pairs = chosen
                .iter()
                .zip(&strips)
                .map(|((_, r), s)| (r, s))
                .collect::<Vec<_>>();
            // The strip's loops grow from the walls round it: the region reaches as far as
            // its farthest point from them (copies compare their growth's end with this
            // bound; a copy's is its representative's).
            let mut reach: Vec<f64> = Vec::with_capacity(pairs.len());
            for (i, (r, s)) in pairs.iter().enumerate() {
                let copied = sources
                    .as_ref()
                    .and_then(|v| v.get(i))
                    .filter(|c| c.0 < i)
                    .map(|c| reach[c.0]);
                reach.push(match (copied, s) {
                    (Some(m), Some(_)) => m,
                    (_, Some((_, _, strip))) => strip.0.iter().fold(r.max_distance, |m, p| {
                        m.max(crate::geometry::regions::max_distance(p, &below_strips))
                    }),
                    (_, None) => r.max_distance,
                });
            }
            extended = pairs
                .into_iter()
                .zip(reach)
                .map(|((r, s), reach)| match s {
                    Some((hint, _, _)) => crate::geometry::Region {
                        polygon: hint.clone(),
                        max_distance: reach,
                        ..(*r).clone()
                    },
                    None => (*r).clone(),
                })
                .collect::<Vec<_>>();
            let strip_sets: Vec<&MultiPolygon<f64>> =
                strips.iter().flatten().map(|(_, _, s)| s).collect();
            // Round the strip the sparse infill is no ground to grow from, and no part of
            // the zone either: its edge there is an outline, which the loops stop short
            // of and a contour and a perimeter follow, as at the part's own edge.
            // (Its outline a little past the slicer's strands: the perimeter along it,
            // pulled in by the inset, then ends where their edge did, and the layer
            // above's infill turns there keep what they rested on.)
            area_strips = crate::geometry::difference(
                area,
                &crate::geometry::difference(
                    &cavities,
                    &crate::geometry::offset(&crate::geometry::union_all(&strip_sets), STRIP_EDGE),
                ),
            );
            (
                extended.iter().zip(others.iter()).collect(),
                &below_strips,
                &area_strips,
            )
        };
        let plans: Vec<(usize, RegionKind, Plan, f64)> = crate::poa::plan_all(
            &jobs,
            below,
            area,
            widths,
            settings,
            start,
            sources.as_ref(),
        )
        .into_iter()
        .zip(chosen.iter())
        .map(|(plan, (id, r))| (*id, r.kind, plan, object_height(layer, r.object)))
        .collect();
        let mut rewrites = Vec::new();
        // (Every plan is accounted for, strip or not.)
        let strips = strips.into_iter().chain(std::iter::repeat(None));
        for (((id, kind, plan, height), strip), (_, region)) in
            plans.into_iter().zip(strips).zip(chosen.iter())
        {
            if plan.strands.is_empty() || leaves_a_hole(&plan) {
                let reason = if self.held_as_sliced(layer, region, widths.loop_width) {
                    HELD_AS_SLICED
                } else {
                    "no loop fits"
                };
                self.report.skipped.push(SkippedRegion {
                    region: id,
                    layer: layer.index + 1,
                    kind,
                    reason: reason.into(),
                });
            } else {
                rewrites.push(RegionRewrite {
                    id,
                    kind,
                    plan,
                    height,
                    no_connect: strip
                        .map(|(_, cavity, _)| cavity)
                        .unwrap_or_else(|| MultiPolygon(Vec::new())),
                });
            }
        }
        Some(rewrites)
    }

    /// Adds a rewritten layer's filament and time (by the estimator, with the limits in
    /// force: `planned`) to the report.
    fn account(&mut self, planned: f64, mut stats: Vec<RewriteStats>) {
        // The estimator plans motion only (`planned`: its time for the layer as rewritten
        // less as sliced); the pauses poa wrote count on top.
        let dwell: f64 = stats.iter().map(|s| s.dwell_s).sum();
        let added = planned + dwell;
        // The planner's time for the layer, shared out like the simple model's estimates.
        let simple: f64 = stats.iter().map(|s| s.time_added_s.max(0.0)).sum();
        let n = stats.len().max(1) as f64;
        for s in &mut stats {
            s.time_added_s = if simple > 0.0 {
                added * s.time_added_s.max(0.0) / simple
            } else {
                added / n
            };
        }
        let report = &mut self.report;
        report.progress.push(crate::progress::Added {
            offset: 0,
            seconds: added,
        });
        for s in stats {
            report.regions_rewritten += 1;
            report.loops += s.loops;
            report.gradual += usize::from(s.gradual);
            report.filament_added_mm += s.written_filament_mm - s.removed_filament_mm;
            report.time_added_s += s.time_added_s;
            report.rewrites.push(s);
        }
    }
}

impl Pass for PoaPass<'_> {
    fn layer(&mut self, d: &crate::geometry::Detected) -> Result<Option<Vec<u8>>, Error> {
        self.layer_under(d, None, &[])
    }
}

impl PoaPass<'_> {
    /// [`Pass::layer`] knowing the layer printed next (`above`, as read), which may rest on
    /// the ends of this layer's strands: those are not cut away; and the regions found on it
    /// (`above_regions`, against this layer as sliced).
    pub fn layer_under(
        &mut self,
        d: &crate::geometry::Detected,
        above: Option<&Layer>,
        above_regions: &[crate::geometry::Region],
    ) -> Result<Option<Vec<u8>>, Error> {
        // Above a rewritten layer the regions are found again on the layer as rewritten:
        // a perimeter moved in there moves this layer's support.
        let redone;
        // Detection leaves out the area of a layer proven supported: made here only when
        // it is needed (a rewrite below or here).
        let own_area = std::cell::OnceCell::new();
        let area = || own_area.get_or_init(|| d.area_or_compute(&self.opts.detect));
        self.joined_below = self.join_below(&d.layer).map(|a| (d.layer.index, a));
        let below_rewritten = match (&self.rewritten_below, &self.joined_below) {
            (Some((i, below)), _) if i + 1 == d.layer.index && d.layer.over_previous() => {
                Some(below)
            }
            (_, Some((k, below))) if *k == d.layer.index => Some(below),
            _ => None,
        };
        let (regions, above_rewrite) = match below_rewritten {
            Some(below) if !d.layer.on_bed() => {
                // The moved perimeters come in pieces: so do the regions they leave.
                let opts = crate::geometry::DetectOptions {
                    min_area: self.opts.detect.min_area.min(0.1),
                    ..self.opts.detect.clone()
                };
                redone = crate::geometry::find_regions(below, &d.layer, area(), &opts);
                (&redone[..], true)
            }
            _ => (&d.regions[..], false),
        };
        let hanging = self.hanging(&d.layer, regions);
        let (chosen, left) = self.choose(d, regions, above_rewrite, &hanging);
        let rewrites = if chosen.is_empty() {
            Vec::new()
        } else {
            // A part's regions are planned in the part's area: support printed beside it is
            // no outline for its perimeter (a hull's bow by PrusaSlicer with support).
            let part = crate::geometry::area::part_area(&d.layer, &self.opts.detect.area);
            self.plan_best(
                d,
                part.as_ref().unwrap_or_else(|| area()),
                &left,
                &chosen,
                above,
                above_regions,
            )
        };
        let layer = &d.layer;
        let below = resting_on(&self.below_layers, layer);
        // The layer as sliced, checked once near every planned zone (samples kept): what
        // `drop_held` reads round each gradual ring, and the judge's "as sliced" side. (Three
        // whole-layer checks a layer cost half of a plate of sloped parts' rewrite.)
        let sliced_window = {
            use geo::BoundingRect;
            window_round(
                rewrites.iter().filter_map(|r| r.plan.zone.bounding_rect()),
                JUDGE_REACH,
            )
        };
        let judged_below = judged_on(&self.below_layers, layer);
        let sliced_check = std::cell::OnceCell::new();
        let sliced = || {
            sliced_check.get_or_init(|| {
                sliced_window.map(|w| {
                    crate::check::check_layer_within(
                        &judged_below,
                        layer,
                        self.motion.filament_area,
                        w,
                    )
                })
            })
        };
        let (rewrites, held, doubtful) =
            drop_held(layer, &below, rewrites, self.width_on(layer), || {
                sliced().as_ref()
            });
        self.report.skipped.extend(held);
        let (rewrites, repeated) = drop_repeated(layer.index + 1, rewrites);
        self.report.skipped.extend(repeated);
        let rewrites: Vec<RegionRewrite> = rewrites
            .into_iter()
            .map(|r| {
                if r.plan.with_perimeter && !below.is_empty() {
                    anchor_gradual(
                        &r,
                        layer,
                        &below,
                        &self.motion,
                        self.opts.settings.flow_factor,
                    )
                } else {
                    r
                }
            })
            .collect();
        let rewrites = if doubtful.is_empty() {
            rewrites
        } else {
            let above_on = above.filter(|a| a.rests_on.contains(&layer.index));
            let in_air = |set: &[RegionRewrite]| -> Option<f64> {
                if set.is_empty() {
                    return sliced().as_ref().map(|c| c.in_air_mm);
                }
                let window = sliced_window?;
                let (bytes, _) = rewrite_layer(
                    layer,
                    &below,
                    above_on,
                    set,
                    &self.motion,
                    &self.opts.settings,
                    BlockPlace::AtEntry,
                );
                let back = reread(layer, &bytes, &self.config)?;
                Some(crate::check::in_air_within(
                    &judged_below,
                    &back,
                    self.motion.filament_area,
                    window,
                ))
            };
            let (kept, dropped) = keeps_gain(rewrites, &doubtful, in_air);
            self.report
                .skipped
                .extend(dropped.into_iter().map(|r| SkippedRegion {
                    region: r.id,
                    layer: layer.index + 1,
                    kind: r.kind,
                    reason: PERIMETER_HELD.into(),
                }));
            kept
        };
        // Only a gradual overhang's plan moves the outline the layer above stands on (a wide
        // region's loops fill its zone, and its perimeter's inset is within the tolerance):
        // the layer above finds its regions on this layer as rewritten only then. (Finding
        // them on a wide rewrite too made a bowl's thin ring over its first wide layer wide,
        // and the ring above hung: 0.7 -> 38.5 mm in air, Cura defaults.) Over a wide
        // rewrite the layer as rewritten is made only when the layer above has regions to
        // plan on it ([`WideBelow`]): buffering every loop of a big region costs as much as
        // the region search. A ladder's rungs fill the strip the slicer printed, as a wide
        // region's loops do (buffering a hook's 97 overlapping rungs cost more than the rest
        // of a plate of four).
        let moves_outline = rewrites.iter().any(|r| r.plan.with_perimeter);
        self.wide_below = None;
        let zones =
            crate::geometry::union_all(&rewrites.iter().map(|r| &r.plan.zone).collect::<Vec<_>>());
        // Kept over layers that move no outline, for a layer printed later that rests on
        // it across them ([`PoaPass::join_below`]); the layer just after it reads it only
        // when it is the one just before.
        self.rewritten_below = if !moves_outline {
            self.rewritten_below
                .take()
                .filter(|(i, _)| i + ABOVE_AHEAD >= layer.index)
        } else {
            let strands = rewrites
                .iter()
                .flat_map(|r| r.plan.strands.iter())
                .map(|s| (&s.points[..], s.width));
            Some((
                layer.index,
                crate::geometry::rewritten_area(area(), &zones, strands),
            ))
        };
        let rewritten = if rewrites.is_empty() {
            None
        } else {
            // The layer as the plan's judge wrote it, when these are the rewrites it wrote.
            let mut cached = self.plain_written.take().filter(|c| {
                c.0 == layer.index
                    && c.1.iter().eq(rewrites.iter().map(|r| &r.id))
                    && rewrites
                        .iter()
                        .all(|r| !r.plan.with_perimeter && !r.plan.ladder)
            });
            let mut attempt = |place: BlockPlace| {
                let (bytes, stats, known) =
                    match cached.take().filter(|_| place == BlockPlace::AtEntry) {
                        Some((_, _, bytes, stats, back)) => (bytes, stats, Some(back)),
                        None => {
                            let (bytes, stats) = rewrite_layer(
                                layer,
                                &below,
                                above.filter(|a| a.rests_on.contains(&layer.index)),
                                &rewrites,
                                &self.motion,
                                &self.opts.settings,
                                place,
                            );
                            (bytes, stats, None)
                        }
                    };
                // The layer read back, and the estimator's time for it as rewritten and as
                // sliced, side by side: on a plate's first floating layer each is a few
                // milliseconds of one core.
                let (back, planned) = rayon::join(
                    || known.unwrap_or_else(|| reread(layer, &bytes, &self.config)),
                    || {
                        let (new, old) = rayon::join(
                            || layer_time(&self.limits, layer, &bytes),
                            || layer_time(&self.limits, layer, &layer.raw),
                        );
                        new - old
                    },
                );
                (bytes, stats, back, planned)
            };
            // Judged where a plan moves the outline (a gradual overhang's, or one on a layer
            // whose own support moved), and where the zones are small: the wide plans of a
            // first floating layer grow from the wall below and cost a plate's worth of
            // samples to judge, while small ones cost little and can do worse than the slicer
            // (a lettering's strokes on a wall, outer wall first: 0 -> 2.3 mm in air).
            let judged = above_rewrite
                || rewrites
                    .iter()
                    .any(|r| r.plan.with_perimeter || r.plan.ladder)
                || rewrites
                    .iter()
                    .map(|r| geo::Area::unsigned_area(&r.plan.zone))
                    .sum::<f64>()
                    < JUDGED_AREA;
            let worse = |back: &Option<Layer>| {
                back.as_ref().filter(|_| judged).and_then(|b| {
                    self.worse_in_air(&judged_below, b, sliced_window.zip(sliced().as_ref()))
                })
            };
            let (mut bytes, mut stats, mut back, mut planned) = attempt(BlockPlace::AtEntry);
            let mut verdict = worse(&back);
            // Written where the wall enters its zone, a gradual overhang's block follows
            // the wall's stretch before it, whose end then has nothing of the block to lean
            // on (a cup handle's ring by Cura: 0.4 mm in air, and the rings above it left as
            // sliced): before the wall, as a block that goes out and back, it may do.
            if verdict.is_some() && rewrites.iter().any(|r| r.plan.with_perimeter) {
                let again = attempt(BlockPlace::BeforeMove);
                let second = worse(&again.2);
                if second.is_none() {
                    (bytes, stats, back, planned) = again;
                    verdict = None;
                }
            }
            if let Some(worse) = verdict {
                // Never worse than the slicer: the layer goes out as sliced.
                for r in &rewrites {
                    self.report.skipped.push(SkippedRegion {
                        region: r.id,
                        layer: layer.index + 1,
                        kind: r.kind,
                        reason: format!(
                            "rewritten, the layer would print {:.1} mm in air, {:.1} as sliced",
                            worse.1, worse.0
                        ),
                    });
                }
                self.rewritten_below = None;
                self.reread = None;
                self.limits.track_limits(&layer.raw);
                self.note_wall_width(layer);
                return Ok(None);
            }
            self.account(planned, stats);
            self.reread = back;
            // A layer whose only rewrites are ladders prints the strips the slicer printed:
            // the layer above is planned on it as detected.
            if !moves_outline && rewrites.iter().any(|r| !r.plan.ladder) {
                self.wide_below = Some(WideBelow {
                    index: layer.index,
                    area: area().clone().into_owned(),
                    zones: zones.clone(),
                    strands: rewrites
                        .iter()
                        .flat_map(|r| r.plan.strands.iter())
                        .map(|s| (s.points.clone(), s.width))
                        .collect(),
                });
            }
            // The layer above is planned on what this layer prints as written: the area
            // made from the plan alone keeps, in places, the slicer's perimeter that the
            // splice took out (an edge a loop above then grew from, in air).
            if let (Some((i, below_area)), Some(r)) = (&self.rewritten_below, &self.reread) {
                if *i == layer.index {
                    // Away from the zones the layer is the slicer's: its area as detected
                    // there (read back, strands cut at a zone's edge can split the infill's
                    // outline into pockets the hole rule leaves open, and the layer above
                    // found a honeycomb's cells over air, layer after layer).
                    let away = crate::geometry::difference(
                        area(),
                        &crate::geometry::margin(&zones, AWAY_FROM_ZONES),
                    );
                    let printed = crate::geometry::union(
                        &crate::geometry::printed_area_any_order(r, &self.opts.detect.area),
                        &away,
                    );
                    let rewritten = crate::geometry::intersection(
                        below_area,
                        &crate::geometry::offset(&printed, REREAD_SLACK),
                    );
                    self.rewritten_below = Some((*i, rewritten));
                }
            }
            Some(bytes)
        };
        self.limits.track_limits(&layer.raw);
        self.note_wall_width(layer);
        Ok(rewritten)
    }
}

/// A box, (min, max) corners.
type Window = ([f64; 2], [f64; 2]);

/// See [`PoaPass::plain_written`].
type PlainWritten = (usize, Vec<usize>, Vec<u8>, Vec<RewriteStats>, Option<Layer>);

/// Farthest (mm) a region may reach from what the layer below printed and be planned: loops
/// a step apart out to there would be thousands, and no printer's bed holds such a cantilever
/// (a fuzzed file's perimeter flung 10 m out took minutes of offsets to plan).
const MAX_REACH: f64 = 500.0;

/// Less in air (mm) round its zones by which a layer rewritten with anchor strips must beat
/// the layer rewritten without them.
const STRIP_GAIN: f64 = 0.5;

/// Margin (mm) round an anchor strip's cavity within which the layer is judged with and
/// without the strip.
const STRIP_JUDGED: f64 = 3.0;

/// Smallest strip (mm2) of a bridge's anchors over sparse infill planned with its region.
const STRIP_MIN: f64 = 2.0;

/// Radius (mm) of the closing that smooths an anchor strip's edge.
const STRIP_SMOOTH: f64 = 1.0;

/// How far (mm) past the slicer's strands an anchor strip's outline lies.
const STRIP_EDGE: f64 = 0.15;

/// Length (mm) of the slicer's strands in an anchor strip that the deposition check must
/// find in air before the strip is planned with its region.
const STRIP_AIR: f64 = 2.0;

/// How far (in loop widths) round an anchor strip the sparse infill below stops counting as
/// what loops grow from.
const STRIP_CAVITY: f64 = 2.0;

/// An anchor strip planned with its region: the region's outline extended by the bridge's
/// strands (the planner's hint), the sparse infill round the strip (no ground to grow
/// from), and the strip.
type Strip = (geo::Polygon<f64>, MultiPolygon<f64>, MultiPolygon<f64>);

/// For each chosen region, where the slicer anchored a bridge across its edge over the
/// sparse infill of the layer `below` (PrusaSlicer lays a bridge's strands a few millimetres
/// into the part beside it, and there they run over the gaps of the infill below: the
/// deposition check finds them in air, 22 mm on the first floating layer of a wing, 48 mm on
/// a shelf's by a 0.6 mm nozzle). `Some((hint, cavity, strip))` where there is such a strip: the
/// region's outline with the bridge's strands that cross it (the zone is what the layer
/// prints in there beyond the area below), and the sparse infill round the strip, taken out of
/// the area below so that loops grow into the strip from the walls that hold it, not from
/// the infill's gaps. The strip's slicer strands are then replaced by loops like the
/// region's own. What hangs is read on `judged`: `layer` itself (its bridge's own strands must
/// hang in the strip), or `layer` rewritten without strips (anything may still hang over the
/// sparse infill). A copy (`sources`) gets its representative's strip, moved.
fn anchor_strips(
    (layer, judged): (&Layer, &Layer),
    (below, resting): (&Layer, &[&Layer]),
    below_area: &MultiPolygon<f64>,
    (chosen, sources): (&Chosen<'_>, &crate::poa::Sources),
    w: f64,
    filament_area: f64,
) -> Vec<Option<Strip>> {
    use geo::{Area, BoundingRect};
    use rayon::prelude::*;
    if chosen.len() > 4 * MAX_STRIP_REGIONS || !below.paths.iter().any(|p| p.role == Role::Infill) {
        return vec![None; chosen.len()];
    }
    // The regions' bridge strands crossing them and the sparse infill near them.
    type Found<'r> = Option<(
        &'r crate::geometry::Region,
        Vec<&'r crate::layers::Path>,
        MultiPolygon<f64>,
    )>;
    let copy_of = |i: usize| sources.get(i).filter(|s| s.0 != i).copied();
    let found: Vec<Found<'_>> = chosen
        .par_iter()
        .enumerate()
        .map(|(i, (_, r))| {
            let r: &crate::geometry::Region = r;
            if r.kind == RegionKind::Floating || copy_of(i).is_some() {
                return None;
            }
            let rb = r.polygon.bounding_rect()?;
            let region = RingIndex::new(&MultiPolygon::new(vec![r.polygon.clone()]));
            // The region's outline grown by a few widths: a bridge strand of the slicer's
            // wholly in there runs beside the region's edge (PrusaSlicer lays the first of
            // a roof's strands along a one-perimeter wall, over the gap between its two
            // beads: 109 mm in air on a box's roof).
            let beside = RingIndex::new(&crate::geometry::offset(
                &MultiPolygon::new(vec![r.polygon.clone()]),
                STRIP_BESIDE * w,
            ));
            // The region's bridge strands that run out of it, and those beside it.
            let crossing: Vec<&crate::layers::Path> = layer
                .paths
                .iter()
                .filter(|p| p.role == Role::BridgeInfill)
                .filter(|p| {
                    let b = crate::geometry::points_box(&p.points);
                    crate::geometry::boxes_within(b.as_ref(), Some(&rb), STRIP_BESIDE * w)
                })
                .filter(|p| {
                    let inside = |q: &[f64; 2]| region.contains(*q);
                    let all_in = p.points.iter().all(inside);
                    !all_in
                        && (p.points.iter().any(inside)
                            || p.points.windows(2).any(|s| {
                                beside.contains([
                                    (s[0][0] + s[1][0]) / 2.0,
                                    (s[0][1] + s[1][1]) / 2.0,
                                ]) || beside.contains(s[0])
                            }))
                })
                .collect();
            let bb = crate::geometry::points_box(
                &crossing
                    .iter()
                    .flat_map(|p| p.points.iter().copied())
                    .collect::<Vec<_>>(),
            )?;
            let near_box = |b: &geo::Rect<f64>| {
                b.max().x >= bb.min().x - 2.0
                    && b.min().x <= bb.max().x + 2.0
                    && b.max().y >= bb.min().y - 2.0
                    && b.min().y <= bb.max().y + 2.0
            };
            let near =
                |pts: &[[f64; 2]]| crate::geometry::points_box(pts).is_some_and(|b| near_box(&b));
            // What holds strands below: everything but its sparse infill.
            let solid = crate::geometry::footprint(
                below
                    .paths
                    .iter()
                    .filter(|p| p.role != Role::Infill && p.role.is_part() && near(&p.points)),
            );
            let window = crate::geometry::offset(&MultiPolygon::new(vec![bb.to_polygon()]), 2.0);
            // (The polygons of the plate's area below near the bridge only.)
            let below_near = MultiPolygon::new(
                below_area
                    .0
                    .iter()
                    .filter(|q| q.bounding_rect().is_some_and(|b| near_box(&b)))
                    .cloned()
                    .collect(),
            );
            let sparse = crate::geometry::difference(
                &crate::geometry::intersection(&below_near, &window),
                &crate::geometry::offset(&solid, 0.01),
            );
            if sparse.unsigned_area() < STRIP_MIN {
                return None;
            }
            Some((r, crossing, sparse))
        })
        .collect();
    // Only where the slicer's strands there hang: a strip the infill below holds (its lines
    // across the strands) is left as sliced. One check of the layer near every region's
    // sparse infill (each on its own read the plate's layers again).
    let windows: Vec<Window> = found
        .iter()
        .flatten()
        .filter_map(|(_, _, sparse)| sparse.bounding_rect())
        .map(|b| {
            (
                [b.min().x - 1.0, b.min().y - 1.0],
                [b.max().x + 1.0, b.max().y + 1.0],
            )
        })
        .collect();
    // (A layer of hundreds of such regions, a damaged file's, keeps its bridges as sliced:
    // every sample would be tested against every box.)
    if windows.is_empty() || windows.len() > MAX_STRIP_REGIONS {
        return vec![None; chosen.len()];
    }
    let in_air: Vec<crate::check::Sample> =
        crate::check::samples_inside(resting, judged, filament_area, &windows)
            .into_iter()
            .filter(|s| s.support == crate::check::Support::InAir)
            .collect();
    let hanging = |area: &MultiPolygon<f64>, of: Option<&std::collections::HashSet<u64>>| -> f64 {
        let index = RingIndex::new(area);
        let Some(b) = area.bounding_rect() else {
            return 0.0;
        };
        in_air
            .iter()
            .filter(|s| {
                let [x, y] = s.point;
                x >= b.min().x && x <= b.max().x && y >= b.min().y && y <= b.max().y
            })
            .filter(|s| of.is_none_or(|l| l.contains(&s.line)))
            .filter(|s| index.contains(s.point))
            .map(|s| s.length)
            .sum()
    };
    let out: Vec<Option<Strip>> = found
        .into_par_iter()
        .map(|f| {
            let (r, crossing, sparse) = f?;
            // (The bridge's own strands first: what else hangs there is no strip's.)
            let lines: std::collections::HashSet<u64> = crossing
                .iter()
                .flat_map(|p| p.seg_line.iter().copied())
                .collect();
            // (The layer as rewritten numbers its lines anew.)
            let lines = std::ptr::eq(layer, judged).then_some(&lines);
            if hanging(&sparse, lines) < STRIP_AIR {
                return None;
            }
            // The strands' footprint near the sparse infill only (a bridge's strands zigzag
            // across a whole cap, its anchors are over the post): their pieces within reach
            // of its box, through the walls round it to the region.
            let sb = sparse.bounding_rect()?;
            let reach = (
                [sb.min().x - STRIP_REACH, sb.min().y - STRIP_REACH],
                [sb.max().x + STRIP_REACH, sb.max().y + STRIP_REACH],
            );
            let pieces: Vec<(Vec<[f64; 2]>, f64)> = crossing
                .iter()
                .flat_map(|p| {
                    pieces_in(&p.points, reach)
                        .into_iter()
                        .map(move |q| (q, p.width))
                })
                .collect();
            let bridges =
                crate::geometry::area::Strands::of_lines(pieces.iter().map(|(q, w)| (&q[..], *w)))
                    .buffer();
            // Its edge smoothed over the steps where the slicer's strands end at different
            // places (a perimeter along a step turned past the loops' reach).
            let strip = crate::geometry::intersection(
                &crate::geometry::opening(
                    &crate::geometry::closing(
                        &crate::geometry::intersection(&bridges, &sparse),
                        STRIP_SMOOTH,
                    ),
                    w,
                ),
                &sparse,
            );
            if strip.unsigned_area() < STRIP_MIN {
                return None;
            }
            // As sliced, the strip's own strands must hang there; as rewritten without it,
            // anything over the sparse infill beside the region (cut anchors, and the part's
            // infill that leaned on them) may.
            if lines.is_some() && hanging(&strip, None) < STRIP_AIR {
                return None;
            }
            let cavity = crate::geometry::intersection(
                &sparse,
                &crate::geometry::offset(&strip, STRIP_CAVITY * w),
            );
            // The bridge's strands join the strip to the region over the walls between them.
            let hint =
                crate::geometry::union(&MultiPolygon::new(vec![r.polygon.clone()]), &bridges);
            let hint = match hint.0.len() {
                1 => hint.0.into_iter().next()?,
                _ => return None,
            };
            Some((hint, cavity, strip))
        })
        .collect::<Vec<_>>();
    // The copies' strips: their representatives', moved.
    (0..out.len())
        .map(|i| match copy_of(i) {
            Some((j, t)) => out[j].as_ref().map(|(hint, cavity, strip)| {
                use geo::Translate;
                (
                    hint.translate(t[0], t[1]),
                    cavity.translate(t[0], t[1]),
                    strip.translate(t[0], t[1]),
                )
            }),
            None => out[i].clone(),
        })
        .collect()
}

/// How far (in loop widths) beside a region a bridge strand of the slicer's that does not
/// enter it is taken for its anchors.
const STRIP_BESIDE: f64 = 3.0;

/// Most regions of a layer whose anchor strips are looked for.
const MAX_STRIP_REGIONS: usize = 64;

/// How far (mm) past the box of the sparse infill beside a region the bridge strands
/// anchored over it are taken for its strip: across the walls round it, to the region.
const STRIP_REACH: f64 = 3.0;

/// The runs of the polyline `points` whose segments meet the box `b` (min, max corners).
fn pieces_in(points: &[[f64; 2]], b: ([f64; 2], [f64; 2])) -> Vec<Vec<[f64; 2]>> {
    let meets = |p: [f64; 2], q: [f64; 2]| {
        p[0].max(q[0]) >= b.0[0]
            && p[0].min(q[0]) <= b.1[0]
            && p[1].max(q[1]) >= b.0[1]
            && p[1].min(q[1]) <= b.1[1]
    };
    let mut out: Vec<Vec<[f64; 2]>> = Vec::new();
    let mut run: Vec<[f64; 2]> = Vec::new();
    for s in points.windows(2) {
        if meets(s[0], s[1]) {
            if run.is_empty() {
                run.push(s[0]);
            }
            run.push(s[1]);
        } else if !run.is_empty() {
            out.push(std::mem::take(&mut run));
        }
    }
    if !run.is_empty() {
        out.push(run);
    }
    out
}

/// Total zone area (mm2) of a layer's rewrites under which the rewritten layer is always
/// judged against the layer as sliced (re-read and checked near the zones).
const JUDGED_AREA: f64 = 100.0;

/// Leaves out the gradual overhangs whose slicer perimeter the deposition check finds
/// held all along, by the layers `below` as printed (poa's rewrite of the layer under it
/// included): moving it would gain nothing there, and the wall above was sliced on it
/// where it is; and the ladders whose slicer loop it finds held or short-bridged. They go to
/// the report. A gradual overhang whose perimeter holds but over whose zone a bridge line
/// hangs in air (laid along a hole's ceiling) is kept, its id in the third list: it is
/// worth its loops only where the layer comes out less in air with it ([`keeps_gain`]).
fn drop_held<'c>(
    layer: &Layer,
    below: &[&Layer],
    rewrites: Vec<RegionRewrite>,
    loop_width: f64,
    sliced: impl FnOnce() -> Option<&'c crate::check::LayerCheck>,
) -> (Vec<RegionRewrite>, Vec<SkippedRegion>, Vec<usize>) {
    if below.is_empty()
        || !rewrites
            .iter()
            .any(|r| r.plan.with_perimeter || r.plan.ladder)
    {
        return (rewrites, Vec::new(), Vec::new());
    }
    let Some(c) = sliced() else {
        return (rewrites, Vec::new(), Vec::new());
    };
    // Every perimeter, not the external one alone: in a hollow part the wall's inner
    // perimeter steps over the void inside the wall below (a lying pipe's bore side at 0 %
    // infill: 56 mm in air a layer, its external perimeter held all along).
    let walls = lines_of(layer, |r| {
        matches!(
            r,
            Role::ExternalPerimeter | Role::OverhangPerimeter | Role::Perimeter
        )
    });
    let unheld: Vec<([f64; 2], bool)> = c
        .samples
        .iter()
        .filter(|s| s.support != crate::check::Support::Supported)
        .filter(|s| walls.binary_search(&s.line).is_ok())
        .map(|s| (s.point, s.support == crate::check::Support::InAir))
        .collect();
    let bridges = lines_of(layer, |r| r == Role::BridgeInfill);
    let hanging: Vec<[f64; 2]> = c
        .samples
        .iter()
        .filter(|s| s.support == crate::check::Support::InAir)
        .filter(|s| bridges.binary_search(&s.line).is_ok())
        .map(|s| s.point)
        .collect();
    let mut kept = Vec::with_capacity(rewrites.len());
    let mut skipped = Vec::new();
    let mut doubtful = Vec::new();
    for r in rewrites {
        let held = (r.plan.with_perimeter || r.plan.ladder) && {
            // The perimeter's centreline runs up to half a width inside the zone's edge.
            let near = crate::geometry::margin(&r.plan.zone, loop_width / 2.0 + 0.05);
            let index = RingIndex::new(&near);
            // A narrow cantilever's walls out and back are a short bridge where they hold at
            // both ends (a letter's stroke 3 mm out of a wall): rungs there cost time for
            // nothing the check sees.
            let held = !unheld
                .iter()
                .any(|(p, in_air)| (*in_air || !r.plan.ladder) && index.contains(*p));
            if held && r.plan.with_perimeter && !hanging.is_empty() {
                let zone = RingIndex::new(&r.plan.zone);
                if hanging.iter().any(|p| zone.contains(*p)) {
                    doubtful.push(r.id);
                    kept.push(r);
                    continue;
                }
            }
            held
        };
        if held {
            skipped.push(SkippedRegion {
                region: r.id,
                layer: layer.index + 1,
                kind: r.kind,
                reason: PERIMETER_HELD.into(),
            });
        } else {
            kept.push(r);
        }
    }
    (kept, skipped, doubtful)
}

/// The rewrites of a layer with or without the `doubtful` ones ([`drop_held`]), whichever
/// leaves the layer less in air (`in_air` of a set, `None` when it cannot be judged): the
/// doubtful ones stay only where they take more than the check's margin out of the air
/// (a bolt block's bridge line along its hole's ceiling: 16.8 mm -> 0); otherwise they
/// cost loops for nothing, or do worse beside the others (a fillet bracket's two rings
/// beside its roof: 0 -> 1.8 mm). Returns (kept, dropped).
fn keeps_gain(
    rewrites: Vec<RegionRewrite>,
    doubtful: &[usize],
    in_air: impl Fn(&[RegionRewrite]) -> Option<f64>,
) -> (Vec<RegionRewrite>, Vec<RegionRewrite>) {
    let sure: Vec<RegionRewrite> = rewrites
        .iter()
        .filter(|r| !doubtful.contains(&r.id))
        .cloned()
        .collect();
    let gain = in_air(&sure).zip(in_air(&rewrites)).map(|(a, b)| a - b);
    if gain.is_some_and(|g| g > WORSE_IN_AIR) {
        (rewrites, Vec::new())
    } else {
        rewrites
            .into_iter()
            .partition(|r| !doubtful.contains(&r.id))
    }
}

/// Share of a rewrite's zone that the zones of the layer's rewrites before it may cover before
/// it is dropped as a repeat of them ([`drop_repeated`]).
const REPEATED_SHARE: f64 = 0.5;

/// Leaves out the rewrites whose zone lies mostly within the zones of the rewrites before them
/// on the layer: those take the slicer's strands out there and fill it already, and a second
/// plan over the same area prints it twice over (a shelf's bridge cut into strips along the
/// slits between its strands, each strip planning the whole zone: 20 plans over one area).
/// They go to the report, named by the rewrite that covers them.
fn drop_repeated(
    layer_number: usize,
    rewrites: Vec<RegionRewrite>,
) -> (Vec<RegionRewrite>, Vec<SkippedRegion>) {
    use geo::{Area, BoundingRect, Intersects};
    if rewrites.len() < 2 {
        return (rewrites, Vec::new());
    }
    let mut kept: Vec<RegionRewrite> = Vec::with_capacity(rewrites.len());
    let mut skipped = Vec::new();
    for r in rewrites {
        let area = r.plan.zone.unsigned_area();
        let bounds = r.plan.zone.bounding_rect();
        let by = bounds.and_then(|b| {
            let near: Vec<&RegionRewrite> = kept
                .iter()
                .filter(|k| {
                    k.plan
                        .zone
                        .bounding_rect()
                        .is_some_and(|kb| kb.intersects(&b))
                })
                .collect();
            if near.is_empty() || area <= 0.0 {
                return None;
            }
            let zones: Vec<&MultiPolygon<f64>> = near.iter().map(|k| &k.plan.zone).collect();
            let covered =
                crate::geometry::intersection(&r.plan.zone, &crate::geometry::union_all(&zones))
                    .unsigned_area();
            (covered > REPEATED_SHARE * area).then(|| {
                near.iter()
                    .map(|k| {
                        let over = crate::geometry::intersection(&r.plan.zone, &k.plan.zone);
                        (over.unsigned_area(), k.id)
                    })
                    .max_by(|a, b| a.0.total_cmp(&b.0))
                    .map_or(0, |(_, id)| id)
            })
        });
        match by {
            Some(id) => skipped.push(SkippedRegion {
                region: r.id,
                layer: layer_number,
                kind: r.kind,
                reason: format!("its zone is planned with region {id}"),
            }),
            None => kept.push(r),
        }
    }
    (kept, skipped)
}

/// The bead height of `object`'s strands on `layer` (where objects of different layer heights
/// share a layer, theirs differ from the layer's height), else the layer's height (0.2 mm when
/// it has none).
fn object_height(layer: &Layer, object: Option<u32>) -> f64 {
    let fallback = if layer.height > 0.0 {
        layer.height
    } else {
        0.2
    };
    let own: Vec<&crate::layers::Path> = layer
        .paths
        .iter()
        .filter(|p| object.is_none() || p.object == object)
        .collect();
    let bead = crate::layers::bead_height(own.iter().copied());
    if bead > 0.0 && bead < 10.0 && (bead - fallback).abs() > 0.1 * fallback {
        bead
    } else {
        fallback
    }
}

/// `layer` as rewritten (`bytes`), read back: the interpreter's state where the layer starts
/// (modes, E counter, position) is stated first, then the bytes go through the layer reader.
/// `None` when the layer has no start state or reads back as no layer.
fn reread(layer: &Layer, bytes: &[u8], config: &SlicerConfig) -> Option<Layer> {
    let start = layer.start.as_deref()?;
    // A G92 shift of X/Y/Z cannot be stated in a line that leaves the next ones alone.
    if start.shifted() {
        return None;
    }
    let p = start.position();
    if !(p.iter().all(|v| v.is_finite()) && start.e_logical().is_finite()) {
        return None;
    }
    // Stated in mm, then the file's own units and distance mode for its lines.
    let mut text = format!(
        "G21\nG90\n{}\nG92 E{}\nG0 X{} Y{} Z{}\n{}{}",
        if start.e_relative() { "M83" } else { "M82" },
        start.e_logical(),
        p[0],
        p[1],
        p[2],
        if start.inches() { "G20\n" } else { "" },
        if start.xyz_relative() { "G91\n" } else { "" }
    )
    .into_bytes();
    text.extend_from_slice(bytes);
    let reader = crate::layers::LayerReader::new(
        &text[..],
        crate::layers::ReaderOptions {
            keep_raw: false,
            config: config.clone(),
        },
    );
    let fa = config.e_area();
    let mut paths = Vec::new();
    for l in reader {
        let l = l.ok()?;
        if l.kind == crate::layers::LayerKind::Layer {
            // Read alone, a layer without height comments (Cura) takes its whole Z as its
            // height, and the widths made from E at that height: put back the layer's own,
            // and the widths from E at it.
            let wrong = l.height;
            let fix = (wrong - layer.height).abs() > 1e-6 && layer.height > 0.0;
            paths.extend(l.paths.into_iter().map(|mut p| {
                if fix && (p.height - wrong).abs() < 1e-9 {
                    let from_e = (p.width - p.e_width(fa)).abs() < 1e-9;
                    p.height = layer.height;
                    if from_e {
                        p.width = p.e_width(fa);
                    }
                }
                p
            }));
        }
    }
    Some(Layer {
        kind: layer.kind,
        index: layer.index,
        marker_number: layer.marker_number,
        z: layer.z,
        height: layer.height,
        rests_on: layer.rests_on.clone(),
        walls_on_previous: layer.walls_on_previous,
        contact: layer.contact.clone(),
        gap_below: layer.gap_below.clone(),
        helical: layer.helical,
        spread: layer.spread,
        paths,
        first_line: layer.first_line,
        last_line: layer.last_line,
        raw: Vec::new(),
        start: None,
        objects: None,
    })
}

/// Blocks detected ahead of the rewrite, at most: a few layers, and no more than
/// [`EMIT_AHEAD_BYTES`] of them (one of any size passes).
const EMIT_AHEAD: usize = 16;
const EMIT_AHEAD_BYTES: usize = 4 << 20;

/// Layers the rewrite holds while it looks for the layer printed on the first of them, at
/// most: this many, and no more than [`ABOVE_AHEAD_BYTES`] (the first is then handed on with
/// no layer above known).
const ABOVE_AHEAD: usize = 8;
const ABOVE_AHEAD_BYTES: usize = 16 << 20;

/// Whether a layer prints any of the part (not support material, a skirt or a wipe tower
/// alone).
fn prints_part(layer: &Layer) -> bool {
    layer.paths.iter().any(|p| p.role.is_part())
}

/// Rewrites a whole file, streaming: reads `input`, writes `output`.
///
/// Long by design: the streaming driver (read, detect, pass, header, footer) whose hand-over of held blocks must stay in one place to be correct.
pub fn process<R: BufRead + Send, S: Sink + Send + ?Sized>(
    input: R,
    config: SlicerConfig,
    opts: &ProcessOptions,
    output: &mut S,
) -> io::Result<ProcessReport> {
    let mut pass = PoaPass::new(&config, opts);
    pass.report.notes = config
        .inferred()
        .iter()
        .map(|(_, why)| why.clone())
        .collect();
    if let Some(note) = fuzzy_note(&opts.detect, config.layer_height().unwrap_or(0.2)) {
        pass.report.notes.push(note);
    }
    let filament_area = pass.motion.filament_area;
    let real_area = crate::layers::filament_area(config.filament_diameter());
    let density = config.filament_density();
    let mut reader = crate::layers::LayerReader::new(
        input,
        crate::layers::ReaderOptions {
            keep_raw: true,
            config,
        },
    );
    let mut emitted = 0u64;
    // Offset in the input of the next layer's first byte: the layers' raw bytes, in order,
    // are the input.
    let mut input_at = 0u64;
    let mut header_written = false;
    // The block held back, in parts: (bytes, offset in the input when they are its bytes).
    type Parts = Vec<(Vec<u8>, Option<u64>)>;
    let mut held: Option<Parts> = None;
    // Each layer is rewritten once the next one is read: an end of a strand the layer above
    // rests on is not cut away.
    let mut handle = |d: crate::geometry::Detected,
                      above: Option<&crate::geometry::Detected>|
     -> io::Result<()> {
        if let Some(n) = &d.layer.objects {
            pass.report.objects.clone_from(n);
        }
        if d.layer.kind == crate::layers::LayerKind::Layer {
            pass.report.layers += 1;
        }
        let at = input_at;
        input_at += d.layer.raw.len() as u64;
        // A layer whose rewrite panics (the polygon library's booleans have, on a cylinder's
        // ring by Cura) goes out as sliced; the rest of the file is rewritten as usual.
        let before = (pass.report.rewrites.len(), pass.report.skipped.len());
        let rewritten = match std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            pass.layer_under(
                &d,
                above.map(|a| &a.layer),
                above.map_or(&[][..], |a| &a.regions[..]),
            )
        })) {
            Ok(r) => r.map_err(io::Error::other)?,
            Err(_) => {
                pass.report.rewrites.truncate(before.0);
                pass.report.skipped.truncate(before.1);
                pass.left_as_sliced_after_panic(&d.layer);
                None
            }
        };
        pass.note_area(d.layer.index, d.area);
        let report = &mut pass.report;
        let mut layer = d.layer;
        // A layer passed through is moved to the output, not copied.
        let from_input = rewritten.is_none().then_some(at);
        let mut bytes = rewritten.unwrap_or_else(|| std::mem::take(&mut layer.raw));
        let parts: Parts = if !header_written && !bytes.is_empty() {
            header_written = true;
            // After the first line: some tools read the slicer's name from line 1.
            let first = memchr::memchr(b'\n', &bytes)
                .map(|i| i + 1)
                .unwrap_or(bytes.len());
            let nl = line_end(&bytes);
            let mut mid = Vec::with_capacity(opts.header.len() + 4);
            if first == bytes.len() && !bytes.ends_with(b"\n") {
                mid.extend_from_slice(nl.as_bytes());
            }
            mid.extend_from_slice(opts.header.as_bytes());
            mid.extend_from_slice(nl.as_bytes());
            let rest = bytes.split_off(first);
            vec![
                (bytes, from_input),
                (mid, None),
                (rest, from_input.map(|a| a + first as u64)),
            ]
        } else {
            vec![(bytes, from_input)]
        };
        for (b, _) in &parts {
            report.has_progress_lines |= has_progress_line(b);
            emitted += b.len() as u64;
        }
        if let Some(last) = report.progress.last_mut().filter(|a| a.offset == 0) {
            last.offset = emitted;
        }
        // One block is held back: the slicer's statistics footer is in the last one.
        if let Some(prev) = held.replace(parts) {
            for (b, from) in prev {
                if !b.is_empty() {
                    output.block(&b, from)?;
                }
            }
        }
        layer.raw = Vec::new();
        pass.keep_below(layer);
        Ok(())
    };
    // Hands each block on once the layer printed on it is there (`None`: the end): the first
    // later layer that rests on it, which is the next one but for layers printed between
    // (support layers interleaved at their own heights, another object's layers on a plate
    // of several layer heights). A hull's tip by PrusaSlicer with support: its perimeter was
    // moved in with nothing known above (the next layer was support alone), and the part's
    // next layer, resting on it across the support layer, hung 25 mm more in air than as
    // sliced (13.5 -> 38.3 mm).
    let mut push = {
        // Each held layer with its weight ([`crate::geometry::detect::weight`]).
        let mut pending: std::collections::VecDeque<(crate::geometry::Detected, usize)> =
            std::collections::VecDeque::new();
        let mut held = 0usize;
        move |d: Option<crate::geometry::Detected>| -> io::Result<()> {
            let end = d.is_none();
            if let Some(d) = d {
                let w = crate::geometry::detect::weight(&d.layer);
                held += w;
                pending.push_back((d, w));
            }
            while let Some((front, _)) = pending.front() {
                let index = front.layer.index;
                let on_it = |part: bool| {
                    pending.iter().skip(1).position(|(a, _)| {
                        a.layer.rests_on.contains(&index) && (!part || prints_part(&a.layer))
                    })
                };
                // The wait is bounded: a layer nothing rests on (an object's top on a plate
                // that goes on) is handed on with none above after a few layers. Support
                // material alone resting on it (support layers at their own heights) stands
                // in only when no layer of the part comes.
                let full = pending.len() > ABOVE_AHEAD || held > ABOVE_AHEAD_BYTES;
                let above = match on_it(true) {
                    Some(k) => Some(k),
                    None if end || full => on_it(false),
                    None => break,
                };
                let Some((p, w)) = pending.pop_front() else {
                    break;
                };
                held -= w;
                handle(p, above.and_then(|k| pending.get(k)).map(|(a, _)| a))?;
            }
            Ok(())
        }
    };
    let checked = |d: &crate::geometry::Detected| {
        if holds_header(&d.layer.raw) {
            Err(already_processed_error())
        } else {
            Ok(())
        }
    };
    if rayon::current_thread_index().is_some() {
        // On a worker of rayon's pool (files of `--out-dir` side by side): one thread, as a
        // worker blocked on a channel would leave the pool's other jobs waiting for it.
        crate::geometry::detect(reader.by_ref(), &opts.detect, |d| {
            checked(&d)?;
            push(Some(d))
        })?;
        push(None)?;
    } else {
        // The rewrite runs on a thread of its own, behind detection: while a plate's first
        // floating layer is planned and spliced (16 caps: 45 ms, most of it on one core),
        // detection goes on proving the layers after it.
        let budget = crate::geometry::detect::Budget::new(EMIT_AHEAD_BYTES);
        let budget = &budget;
        std::thread::scope(|s| -> io::Result<()> {
            // Light layers go over in bundles, as from the reader (one hand-over per layer
            // of a few strands cost more than the layer).
            type Bundle = Vec<crate::geometry::Detected>;
            let (tx, rx) = std::sync::mpsc::sync_channel::<(Bundle, usize)>(EMIT_AHEAD);
            let emitter = s.spawn(move || -> io::Result<()> {
                // Frees the budget however this ends (an error or a panic here), so that
                // detection waiting for it goes on to find the channel closed.
                let _release = budget.release_on_drop();
                for (ds, w) in rx {
                    budget.give(w);
                    for d in ds {
                        push(Some(d))?;
                    }
                }
                push(None)
            });
            let (mut bundle, mut bundle_w): (Bundle, usize) = (Vec::new(), 0);
            // A closed channel: the rewrite stopped on an error, which it returns.
            let send = |bundle: &mut Bundle, w: &mut usize| -> io::Result<()> {
                budget.take(*w);
                let sent = tx.send((std::mem::take(bundle), *w));
                *w = 0;
                sent.map_err(|_| io::Error::other("the rewrite stopped"))
            };
            let detected = crate::geometry::detect(reader.by_ref(), &opts.detect, |d| {
                checked(&d)?;
                bundle_w += crate::geometry::detect::weight(&d.layer);
                bundle.push(d);
                if crate::geometry::detect::bundle_full(bundle.len(), bundle_w) {
                    send(&mut bundle, &mut bundle_w)?;
                }
                Ok(())
            })
            .and_then(|()| {
                if bundle.is_empty() {
                    Ok(())
                } else {
                    send(&mut bundle, &mut bundle_w)
                }
            });
            drop(tx);
            let emitted = emitter
                .join()
                .unwrap_or_else(|p| std::panic::resume_unwind(p));
            // The rewrite's own error first: detection's "stopped" is its echo.
            emitted.and(detected)
        })?;
    }
    let layers_e = pass.layers_e;
    let mut report = pass.report;
    // A file whose slicer states filament but whose layers extrude (almost) nothing keeps its
    // extruder on another axis (PrusaSlicer's mach3 and machinekit flavours write A): say so,
    // rather than "0 regions" alone.
    if let Some(f) = reader
        .facts()
        .stated_filament_mm
        .filter(|f| *f > 0.0 && layers_e < 0.01 * f)
    {
        report.notes.push(format!(
            "no extrusion (E) read in the layers, though the slicer states {f:.0} mm of filament: the extruder may be on another axis (mach3 and machinekit write A), which poa does not read; the file is left as sliced"
        ));
    }
    // The sums above are in E units; where E is a volume (Marlin (Volumetric), UltiGCode,
    // `use_volumetric_e`) the report and the footer say filament, as the slicer does (a
    // mushroom's cap by Cura's volumetric flavour reported +46 mm for +19).
    report.filament_added_mm *= filament_area / real_area;
    report.filament_added_cm3 = report.filament_added_mm * real_area / 1000.0;
    report.filament_added_g = report.filament_added_cm3 * density;
    if let Some(last) = held {
        if report.regions_rewritten > 0 {
            output.block(
                &update_footer(
                    &last
                        .into_iter()
                        .map(|(b, _)| b)
                        .collect::<Vec<_>>()
                        .concat(),
                    report.filament_added_mm,
                    report.time_added_s,
                    real_area,
                    density,
                ),
                None,
            )?;
        } else {
            for (b, from) in last {
                if !b.is_empty() {
                    output.block(&b, from)?;
                }
            }
        }
    }
    report.slicer = reader.facts().slicer.name().to_string();
    Ok(report)
}

/// Where the layer above prints past this layer's outline (`outline`) near `region` and the
/// rewrite keeps its strands as sliced ([`crate::poa::Others::overhung`]): its bridges and
/// floating regions (`above_regions`, found against this layer as sliced) within the
/// planner's reach of the region, and its strands' stretches outside the outline near the
/// region (a slope stepping out half a bead or more where no region is found: a tilted ring's
/// crown by PrusaSlicer, whose layer above bridged 0.5 -> 5.9 mm over the perimeter pulled
/// in), each grown by `reach`. Its overhangs are left out: their loops are planned on this
/// layer's print as rewritten and grow from the perimeter wherever it lies (a hull's sharp
/// bow by PrusaSlicer, its perimeter left out under the layer above's flare: that layer's
/// gradual loops at the tip 0 -> 1.7 mm in air).
fn overhung(
    above: &Layer,
    above_regions: &[crate::geometry::Region],
    outline: &RingIndex,
    region: &crate::geometry::Region,
    widths: &crate::poa::Widths,
) -> MultiPolygon<f64> {
    use geo::BoundingRect;
    let none = || MultiPolygon::new(Vec::new());
    let Some(b) = region.polygon.bounding_rect() else {
        return none();
    };
    let we = widths.perimeter_width;
    let boxed =
        |m: f64| move |q: geo::Rect<f64>| crate::geometry::boxes_within(Some(&b), Some(&q), m);
    let far = boxed(region.max_distance.min(1000.0) + widths.tolerance + 3.0 * we);
    let kept: Vec<geo::Polygon<f64>> = above_regions
        .iter()
        .filter(|r| r.kind != RegionKind::Overhang)
        .filter(|r| r.polygon.bounding_rect().is_some_and(&far))
        .map(|r| r.polygon.clone())
        .collect();
    // The region's perimeter lies within the tolerance and a few widths of its box.
    let m = widths.tolerance + 3.0 * we;
    let near_box = boxed(m);
    let mut pokes: Vec<crate::geometry::Polyline> = Vec::new();
    let mut points = 0usize;
    // (No outline near by: nothing to stand past; every strand would read as outside it.)
    for p in above
        .paths
        .iter()
        .filter(|p| !p.role.is_support() && !outline.is_empty())
    {
        if p.points.len() < 2 || !crate::geometry::points_box(&p.points).is_some_and(&near_box) {
            continue;
        }
        // The stretches between the ones inside, longer than a tenth of a width (a strand
        // touching the outline is not past it).
        let inside = outline.inside_intervals(&p.points);
        let total = crate::geometry::polyline_length(&p.points);
        let mut from = 0.0;
        for (a, z) in inside
            .iter()
            .copied()
            .chain(std::iter::once((total, total)))
        {
            if a - from > 0.1 * we {
                let piece = sub_polyline(&p.points, from, a);
                points += piece.len();
                pokes.push(piece);
            }
            from = z;
        }
        if points > MAX_POKE_POINTS {
            // A layer above that stands far past this one (a file moved off by a stray
            // G91): no slope stepping out, and buffering it all would cost what its region
            // search did. The perimeter keeps its inset there.
            pokes.clear();
            break;
        }
    }
    let own: Vec<geo::Polygon<f64>> = above_regions
        .iter()
        .filter(|r| r.kind == RegionKind::Overhang && r.area >= SMALL_REGION)
        .filter(|r| r.polygon.bounding_rect().is_some_and(&far))
        .map(|r| r.polygon.clone())
        .collect();
    if !own.is_empty() && !pokes.is_empty() {
        let own = crate::geometry::offset(&MultiPolygon::new(own), we);
        pokes = crate::geometry::clip_lines(&pokes, &own, false);
    }
    let mut out = MultiPolygon::new(kept);
    if !pokes.is_empty() {
        let poked =
            crate::geometry::area::Strands::of_lines(pokes.iter().map(|l| (&l[..], we))).buffer();
        out = crate::geometry::union(&out, &poked);
    }
    out
}

/// What fuzzy skin does to the rewrite, when the file has it and the tolerance is automatic:
/// slopes under the tolerance grown by its thickness are left as sliced.
fn fuzzy_note(detect: &crate::geometry::DetectOptions, height: f64) -> Option<String> {
    let t = detect.fuzzy_skin;
    if t <= 0.0 || !matches!(detect.tolerance, crate::geometry::Tolerance::Auto) {
        return None;
    }
    let tol = detect.tolerance_at(height);
    Some(format!(
        "fuzzy skin {t:.2} mm: the tolerance is {tol:.3} mm, so slopes flatter than {:.0} degrees from vertical (at {height} mm layers) are left as sliced",
        (tol / height).atan().to_degrees()
    ))
}

/// Print time of `text` (a layer's lines) from the machine state where `layer` starts, with
/// the limits in force there.
fn layer_time(limits: &crate::estimate::Estimator, layer: &Layer, text: &[u8]) -> f64 {
    let start = layer.start.as_deref().cloned().unwrap_or_default();
    crate::estimate::run_text(limits, &start, text).0
}

/// Whether `block` holds an `M73` line.
fn has_progress_line(block: &[u8]) -> bool {
    block.starts_with(b"M73") || memchr::memmem::find(block, b"\nM73").is_some()
}

/// Updates the statistics a binary G-code file states in its metadata blocks (`key=value`
/// lines: filament used, estimated printing time) for what the rewrite added, and records
/// PrusaSlicer writes the same statistics into the print and slicer metadata.
pub fn update_binary_metadata(file: &mut crate::bgcode::Bgcode, report: &ProcessReport) {
    use crate::bgcode::BlockKind;
    if report.regions_rewritten == 0 {
        return;
    }
    for block in &mut file.blocks {
        if !matches!(
            block.kind,
            BlockKind::PrintMetadata | BlockKind::SlicerMetadata
        ) {
            continue;
        }
        // `key=value` becomes `; key = value` for the footer logic, and back.
        let mut old_g = None;
        let mut out = Vec::with_capacity(block.payload.len() + 32);
        let mut changed = false;
        for line in block.payload.split_inclusive(|&b| b == b'\n') {
            let body = strip_terminator(line);
            let text = String::from_utf8_lossy(body);
            let new = text.split_once('=').and_then(|(k, v)| {
                let as_footer = format!("; {} = {}", k.trim(), v.trim());
                footer_line(
                    &as_footer,
                    report.filament_added_mm,
                    report.filament_added_cm3,
                    report.filament_added_g,
                    report.time_added_s,
                    &mut old_g,
                )
                .map(|f| {
                    let v = f.split_once(" = ").map(|x| x.1).unwrap_or("");
                    format!("{}={}", k, v)
                })
            });
            match new {
                Some(n) => {
                    changed = true;
                    out.extend_from_slice(n.as_bytes());
                    out.extend_from_slice(&line[body.len()..]);
                }
                None => out.extend_from_slice(line),
            }
        }
        if changed {
            block.payload = out;
            block.forget_stored();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_failing_output_stops_the_rewrite_without_waiting_forever() {
        // Layers weighing more in all than the rewrite's queue may hold, written to an output
        // that fails once the queue is full: detection must find the rewrite gone, not wait
        // for budget it would never get back.
        let mut g = String::from("; generated by PrusaSlicer 2.5.0\nM83\nG21\n");
        let pad = format!(";{}\n", "x".repeat(1000));
        for i in 0..30 {
            let z = 0.2 * (i + 1) as f64;
            g += &format!(";LAYER_CHANGE\n;Z:{z:.1}\n;HEIGHT:0.2\nG1 Z{z:.1} F600\n");
            g += ";TYPE:External perimeter\n;WIDTH:0.45\nG1 X10 Y10 F3000\n";
            for (x, y) in [(30, 10), (30, 30), (10, 30), (10, 10)] {
                g += &format!("G1 X{x} Y{y} E0.8\n");
            }
            // Heavier than the queue's share of a layer: its budget fills before its slots.
            g += &pad.repeat(EMIT_AHEAD_BYTES / EMIT_AHEAD / 1000 + 20);
        }
        struct Failing;
        impl Write for Failing {
            fn write(&mut self, _: &[u8]) -> io::Result<usize> {
                // Long enough for detection to fill the queue and wait for budget.
                std::thread::sleep(std::time::Duration::from_millis(300));
                Err(io::Error::other("disk full"))
            }
            fn flush(&mut self) -> io::Result<()> {
                Ok(())
            }
        }
        let config = SlicerConfig::parse(g.as_bytes());
        let opts = test_options(&config);
        assert!(g.len() > 2 * EMIT_AHEAD_BYTES);
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let r = process(g.as_bytes(), config, &opts, &mut Plain(Failing));
            let _ = tx.send(r.map(|_| ()).map_err(|e| e.to_string()));
        });
        let r = rx
            .recv_timeout(std::time::Duration::from_secs(120))
            .expect("process returned");
        assert_eq!(r.unwrap_err(), "disk full");
    }

    /// The default options for `config`'s file, as `poa process` makes them.
    fn test_options(config: &SlicerConfig) -> ProcessOptions {
        ProcessOptions {
            detect: crate::report::detect_options(config),
            settings: PoaSettings::default(),
            objects: ObjectFilter::default(),
            header: "; poa test".into(),
        }
    }

    #[test]
    fn a_file_extruding_on_another_axis_says_so() {
        // PrusaSlicer's mach3 flavour: the extruder is the A axis. Nothing is read as
        // extruded; the report says why instead of "0 regions" alone, and the file passes.
        let mut g = String::from("; generated by PrusaSlicer 2.5.0\nG21\nG90\nM83\n");
        for i in 1..=3 {
            g += &format!(
                ";LAYER_CHANGE\n;Z:{}\nG1 Z{}\n",
                0.2 * i as f64,
                0.2 * i as f64
            );
            g += "G1 X0 Y0\nG1 X10 Y0 A0.5\nG1 X10 Y10 A0.5\n";
        }
        let with_total = |g: &str| -> ProcessReport {
            let config = SlicerConfig::parse(g.as_bytes());
            let opts = test_options(&config);
            let mut out = Vec::new();
            process(g.as_bytes(), config, &opts, &mut Plain(&mut out)).unwrap()
        };
        let said = |r: &ProcessReport| r.notes.iter().any(|n| n.contains("another axis"));
        let stated = format!("{g}; filament used [mm] = 100.0\n");
        let r = with_total(&stated);
        assert!(said(&r), "{:?}", r.notes);
        assert_eq!(r.regions_found, 0);
        // Without a stated filament (nothing to compare with) nothing is said; nor where
        // the layers extrude.
        assert!(!said(&with_total(&g)));
        let e = stated.replace(" A0.5", " E0.5");
        assert!(!said(&with_total(&e)));
    }

    fn loop_strand(loop_index: usize, points: Vec<[f64; 2]>) -> Strand {
        Strand {
            kind: StrandKind::Loop,
            loop_index,
            points,
            width: 0.45,
        }
    }

    #[test]
    fn a_gradual_ring_in_pieces_apart_is_written_piece_by_piece() {
        use crate::geometry::testutil::{mp, rect};
        // A chamfer's ring on two opposite sides of a box, 20 mm apart: one block each.
        let rewrite = |zone: MultiPolygon<f64>, strands: Vec<Strand>| RegionRewrite {
            id: 7,
            kind: RegionKind::Overhang,
            plan: Plan {
                zone,
                strands,
                loops: 1,
                with_perimeter: true,
                ladder: false,
            },
            height: 0.2,
            no_connect: MultiPolygon::new(Vec::new()),
        };
        let sides = mp(vec![rect(0.0, 0.0, 20.0, 0.5), rect(0.0, 20.0, 20.0, 20.5)]);
        let strands = vec![
            loop_strand(1, vec![[0.0, 0.25], [20.0, 0.25]]),
            loop_strand(1, vec![[0.0, 20.25], [20.0, 20.25]]),
        ];
        let r = rewrite(sides.clone(), strands.clone());
        let parts = by_zone_piece(&r);
        assert_eq!(parts.len(), 2);
        for p in &parts {
            assert_eq!(p.plan.zone.0.len(), 1);
            assert_eq!(p.plan.strands.len(), 1);
            let y = p.plan.strands[0].points[0][1];
            let b = geo::BoundingRect::bounding_rect(&p.plan.zone).unwrap();
            assert!(y >= b.min().y && y <= b.max().y);
        }
        // A piece with no strand of its own keeps the rewrite whole (its slicer strands
        // would be taken out with nothing laid), and so does a wide region's plan.
        let three = mp(vec![
            rect(0.0, 0.0, 20.0, 0.5),
            rect(0.0, 20.0, 20.0, 20.5),
            rect(40.0, 0.0, 41.0, 20.0),
        ]);
        assert_eq!(by_zone_piece(&rewrite(three, strands.clone())).len(), 1);
        let mut wide = rewrite(sides, strands);
        wide.plan.with_perimeter = false;
        assert_eq!(by_zone_piece(&wide).len(), 1);
        // The pieces' statistics add up to the region's.
        let st = |len: f64, hop: f64| RewriteStats {
            region: 7,
            strands: 1,
            written_length_mm: len,
            inner_travel_mm: hop,
            longest_inner_travel_mm: hop,
            inserted_before_line: (len * 10.0) as u64,
            ..Default::default()
        };
        let merged = merge_stats(vec![st(20.0, 1.0), st(30.0, 2.0), st(5.0, 0.0)], &[0, 0, 1]);
        assert_eq!(merged.len(), 2);
        assert_eq!(merged[0].strands, 2);
        assert!((merged[0].written_length_mm - 50.0).abs() < 1e-9);
        assert!((merged[0].inner_travel_mm - 3.0).abs() < 1e-9);
        assert!((merged[0].longest_inner_travel_mm - 2.0).abs() < 1e-9);
        assert_eq!(merged[0].inserted_before_line, 200);
        assert!((merged[1].written_length_mm - 5.0).abs() < 1e-9);
    }

    /// A rewrite of region `id` over `zone`: one loop, 0.3 mm high.
    fn one_loop(id: usize, kind: RegionKind, zone: MultiPolygon<f64>) -> RegionRewrite {
        RegionRewrite {
            id,
            kind,
            plan: Plan {
                zone,
                strands: vec![loop_strand(1, vec![[0.0, 0.0], [1.0, 0.0]])],
                loops: 1,
                with_perimeter: false,
                ladder: false,
            },
            height: 0.3,
            no_connect: MultiPolygon::new(Vec::new()),
        }
    }

    #[test]
    fn a_rewrite_whose_zone_others_on_the_layer_fill_already_is_dropped() {
        use crate::geometry::testutil::{mp, rect};
        let rewrite = |id: usize, zone: MultiPolygon<f64>| one_loop(id, RegionKind::Bridge, zone);
        // A shelf's zone planned whole by region 30, a strip of it planned again by 39, and
        // a region beside the shelf (overlapping it by a fifth) and one far off.
        let v = vec![
            rewrite(30, mp(vec![rect(0.0, 0.0, 10.0, 15.0)])),
            rewrite(39, mp(vec![rect(2.0, 0.0, 3.0, 15.0)])),
            rewrite(40, mp(vec![rect(9.0, 0.0, 14.0, 15.0)])),
            rewrite(41, mp(vec![rect(50.0, 0.0, 51.0, 5.0)])),
        ];
        let (kept, skipped) = drop_repeated(68, v);
        let ids: Vec<usize> = kept.iter().map(|r| r.id).collect();
        assert_eq!(ids, [30, 40, 41]);
        assert_eq!(skipped.len(), 1);
        assert_eq!((skipped[0].region, skipped[0].layer), (39, 68));
        assert!(
            skipped[0].reason.contains("region 30"),
            "{}",
            skipped[0].reason
        );
        // Covered by two before it together (each a third): dropped too.
        let v = vec![
            rewrite(1, mp(vec![rect(0.0, 0.0, 4.0, 4.0)])),
            rewrite(2, mp(vec![rect(6.0, 0.0, 10.0, 4.0)])),
            rewrite(3, mp(vec![rect(2.0, 0.0, 8.0, 4.0)])),
        ];
        let (kept, _) = drop_repeated(1, v);
        assert_eq!(kept.len(), 2);
    }

    #[test]
    fn poa_s_tags_follow_the_file_s_dialect() {
        let seen = |lines: &[&str]| {
            let mut t = Tags::default();
            for l in lines {
                t.see(l.as_bytes());
            }
            (t.loops_role(), t.width_line(0.45))
        };
        assert_eq!(
            seen(&[";LAYER_CHANGE", ";TYPE:External perimeter", ";WIDTH:0.45"]),
            (";TYPE:Overhang perimeter", ";WIDTH:0.45".to_string())
        );
        assert_eq!(
            seen(&[";TYPE:Outer wall", ";WIDTH:0.42"]),
            (";TYPE:Overhang wall", ";WIDTH:0.45".to_string())
        );
        let bambu = ("; FEATURE: Overhang wall", "; LINE_WIDTH: 0.45".to_string());
        assert_eq!(seen(&["; FEATURE: Inner wall"]), bambu);
        // Before any role line of the layer: its layer tags tell.
        assert_eq!(seen(&["; CHANGE_LAYER", "; Z_HEIGHT: 0.4"]), bambu);
        assert_eq!(seen(&[";TYPE:WALL-OUTER"]).0, ";TYPE:Overhang perimeter");
    }

    #[test]
    fn rewrites_kept_for_a_hanging_bridge_stay_only_where_they_take_it_out_of_the_air() {
        use crate::geometry::testutil::{mp, rect};
        let rewrite = |id: usize| {
            let zone = mp(vec![rect(id as f64, 0.0, id as f64 + 0.5, 5.0)]);
            let mut r = one_loop(id, RegionKind::Overhang, zone);
            r.plan.with_perimeter = true;
            r
        };
        let ids = |v: &[RegionRewrite]| v.iter().map(|r| r.id).collect::<Vec<_>>();
        // The layer's in air with a set of rewrites: region 7's loops replace a bridge line
        // hanging 16.8 mm over its zone; region 9's make 1.8 mm worse beside region 8's.
        let judge = |v: &[RegionRewrite]| -> Option<f64> {
            let has = |id| v.iter().any(|r| r.id == id);
            Some(if has(7) { 0.0 } else { 16.8 } + if has(9) { 1.8 } else { 0.0 })
        };
        let (kept, dropped) = keeps_gain(vec![rewrite(6), rewrite(7), rewrite(8)], &[7], judge);
        assert_eq!((ids(&kept), ids(&dropped)), (vec![6, 7, 8], vec![]));
        let (kept, dropped) = keeps_gain(vec![rewrite(8), rewrite(9)], &[9], judge);
        assert_eq!((ids(&kept), ids(&dropped)), (vec![8], vec![9]));
        // A gain within the check's margin costs loops for nothing; a layer that cannot be
        // judged keeps to the rule that left such rings as sliced.
        let small = |v: &[RegionRewrite]| Some(if v.len() == 2 { 1.0 } else { 1.2 });
        let (kept, dropped) = keeps_gain(vec![rewrite(1), rewrite(2)], &[2], small);
        assert_eq!((ids(&kept), ids(&dropped)), (vec![1], vec![2]));
        let (kept, dropped) = keeps_gain(vec![rewrite(1), rewrite(2)], &[2], |_| None);
        assert_eq!((ids(&kept), ids(&dropped)), (vec![1], vec![2]));
    }

    #[test]
    fn a_plan_of_perimeters_only_over_a_wide_zone_is_not_laid() {
        use crate::geometry::testutil::{mp, rect};
        let ring = |x0: f64, y0: f64, x1: f64, y1: f64| Strand {
            kind: StrandKind::Perimeter,
            loop_index: 0,
            points: vec![[x0, y0], [x1, y0], [x1, y1], [x0, y1], [x0, y0]],
            width: 0.45,
        };
        let plan = |zone, loops| Plan {
            zone,
            strands: vec![ring(0.2, 0.2, 4.8, 8.8)],
            loops,
            with_perimeter: false,
            ladder: false,
        };
        // A 5 x 9 mm first layer: its perimeter alone would take out its solid infill.
        assert!(leaves_a_hole(&plan(mp(vec![rect(0.0, 0.0, 5.0, 9.0)]), 0)));
        // A ring under the perimeter (a gradual overhang's): the perimeter fills it.
        let thin = crate::geometry::difference(
            &mp(vec![rect(0.0, 0.0, 5.0, 9.0)]),
            &mp(vec![rect(0.45, 0.45, 4.55, 8.55)]),
        );
        assert!(!leaves_a_hole(&plan(thin, 0)));
        // Loops that fill the zone leave none of it bare; loops that stop short do.
        let wide = mp(vec![rect(0.0, 0.0, 5.0, 9.0)]);
        let filled = Plan {
            strands: (0..23)
                .map(|i| {
                    loop_strand(
                        1,
                        vec![[0.0, 0.2 + 0.4 * i as f64], [5.0, 0.2 + 0.4 * i as f64]],
                    )
                })
                .collect(),
            ..plan(wide.clone(), 23)
        };
        assert!(!leaves_a_hole(&filled));
        assert!(leaves_a_hole(&plan(wide, 3)));
    }

    #[test]
    fn short_strokes_are_joined_by_connectors_long_loops_and_gaps_travelled() {
        // Strokes 1.3 mm long across a narrow arm, 0.27 mm apart: joined.
        let a = loop_strand(1, vec![[0.0, 0.0], [1.3, 0.0]]);
        let b = loop_strand(2, vec![[1.3, 0.27], [0.0, 0.27]]);
        assert!(connects(&a, &b));
        // Not to a perimeter, not back to an earlier loop, not two loops on.
        let mut p = b.clone();
        p.kind = StrandKind::Perimeter;
        assert!(!connects(&a, &p));
        assert!(!connects(&b, &loop_strand(1, a.points.clone())));
        assert!(!connects(&a, &loop_strand(3, b.points.clone())));
        // A hop that is a small share of a long loop stays a travel.
        let long = loop_strand(2, vec![[1.3, 0.27], [-20.0, 0.27]]);
        assert!(!connects(&a, &long));
        // Farther than two widths: travelled.
        let far = loop_strand(2, vec![[1.3, 1.0], [0.0, 1.0]]);
        assert!(!connects(&a, &far));
        // A hop straight on past the end, to a piece beyond a gap, leaves both beads.
        let beyond = loop_strand(2, vec![[2.1, 0.0], [2.1, -1.3]]);
        assert!(!connects(&a, &beyond));
    }

    #[test]
    fn no_connector_is_laid_over_an_anchor_strip_s_cavity() {
        // A cavity of sparse infill from x 1 to 2: a step there, or ending or starting
        // there, is kept off it; steps beside it are not.
        let cavity = MultiPolygon::new(vec![geo::Rect::new(
            geo::coord! { x: 1.0, y: -1.0 },
            geo::coord! { x: 2.0, y: 1.0 },
        )
        .to_polygon()]);
        assert!(over_area(&cavity, [1.5, 0.0], [1.5, 0.27]));
        assert!(over_area(&cavity, [0.9, 0.0], [1.2, 0.0]));
        assert!(over_area(&cavity, [0.5, 0.0], [1.5, 0.0]));
        assert!(!over_area(&cavity, [0.0, 0.0], [0.5, 0.27]));
        assert!(!over_area(
            &MultiPolygon::new(vec![]),
            [1.5, 0.0],
            [1.5, 0.27]
        ));
    }

    #[test]
    fn fuzzy_skin_is_noted_only_with_the_automatic_tolerance() {
        let mut d = crate::geometry::DetectOptions::default();
        assert_eq!(fuzzy_note(&d, 0.2), None);
        d.fuzzy_skin = 0.3;
        let note = fuzzy_note(&d, 0.2).unwrap();
        // (0.225 + 0.3) / 0.2: 69 degrees.
        assert!(
            note.contains("0.525 mm") && note.contains("69 degrees"),
            "{note}"
        );
        d.tolerance = crate::geometry::Tolerance::Distance(0.3);
        assert_eq!(fuzzy_note(&d, 0.2), None);
    }

    #[test]
    fn hops_over_the_laid_strands_are_told_from_hops_over_nothing() {
        // Strokes across a crescent, 0.3 mm apart: back along the stroke just laid to the
        // next one's start, 1.7 mm, over it all the way.
        let first: &[[f64; 2]] = &[[0.0, 0.0], [5.0, 0.0]];
        let second: &[[f64; 2]] = &[[0.0, 0.3], [3.0, 0.3]];
        assert!(over_laid([first], [5.0, 0.0], [3.3, 0.3], 0.45));
        assert!(over_laid([first, second], [3.0, 0.3], [0.5, 0.6], 0.45));
        // Past the end of every strand: over nothing laid yet.
        assert!(!over_laid([first, second], [5.0, 0.0], [6.5, 0.0], 0.45));
        // Across a gap between two strands a millimetre apart.
        let far: &[[f64; 2]] = &[[0.0, 2.0], [5.0, 2.0]];
        assert!(!over_laid([first, far], [5.0, 0.0], [5.0, 2.0], 0.45));
        assert!(!over_laid([], [0.0, 0.0], [1.0, 0.0], 0.45));
    }

    #[test]
    fn a_layer_read_back_keeps_its_height_and_widths() {
        // Cura writes no height comments: read alone, the layer at Z 0.4 would take 0.4 mm as
        // its height (nothing below it) and make its widths from E at that height.
        let src = ";FLAVOR:Marlin\nM82\n;LAYER:0\nG1 Z0.2 F300\nG1 X0 Y0\nG1 X10 Y0 E0.5\n\
                   ;LAYER:1\nG1 Z0.4\nG1 X0 Y1\nG1 X10 Y1 E1.0\n";
        let config = SlicerConfig::parse(src.as_bytes());
        let layers: Vec<Layer> = crate::layers::LayerReader::new(
            src.as_bytes(),
            crate::layers::ReaderOptions {
                keep_raw: true,
                config: config.clone(),
            },
        )
        .map(|l| l.unwrap())
        .filter(|l| l.kind == crate::layers::LayerKind::Layer)
        .collect();
        let l = &layers[1];
        assert!((l.height - 0.2).abs() < 1e-9);
        let back = reread(l, &l.raw, &config).expect("read back");
        assert_eq!(back.paths.len(), l.paths.len());
        for (a, b) in back.paths.iter().zip(&l.paths) {
            assert!(
                (a.height - b.height).abs() < 1e-9,
                "{} vs {}",
                a.height,
                b.height
            );
            assert!(
                (a.width - b.width).abs() < 1e-9,
                "{} vs {}",
                a.width,
                b.width
            );
        }
    }

    /// A strand of a 0.45 mm bead at 0.2 mm on 1.75 mm filament, each segment its own line
    /// from `line` on.
    fn bead(role: Role, pts: &[[f64; 2]], line: u64) -> crate::layers::Path {
        let fa = crate::layers::filament_area(1.75);
        let area = (0.45 - 0.2) * 0.2 + std::f64::consts::PI * 0.04 / 4.0;
        let mut p = crate::layers::testing::path(role, 0.45, pts);
        p.seg_e = pts
            .windows(2)
            .map(|w| polyline_length(w) * area / fa)
            .collect();
        p.seg_line = (line..line + pts.len() as u64 - 1).collect();
        p
    }

    #[test]
    fn a_dangling_infill_end_is_anchored_or_cut_only_when_nothing_rests_on_it() {
        use crate::layers::testing::layer;
        let fa = crate::layers::filament_area(1.75);
        // Below: a line along X to X 10 (its bead to 10.2), and a wall along Y at X 12.
        let line_below = bead(Role::Infill, &[[0.0, 0.0], [10.0, 0.0]], 1);
        let wall = bead(Role::Perimeter, &[[12.0, -5.0], [12.0, 5.0]], 2);
        // This layer: infill along the line, 1.3 mm past its end (line 100 is the move).
        let strand = bead(Role::Infill, &[[2.0, 0.0], [11.3, 0.0]], 100);
        let here = layer(1, vec![strand]);
        // A zone near by (within 10 mm), not touching the strand's end.
        let zone = MultiPolygon::new(vec![geo::Rect::new(
            geo::coord! {x: 14.0, y: -3.0},
            geo::coord! {x: 20.0, y: 3.0},
        )
        .to_polygon()]);
        let boxes = [geo::BoundingRect::bounding_rect(&zone)];
        let zones = [&zone];
        let empty = layer(2, Vec::new());
        let run = |below: &Layer, above: Option<&Layer>| {
            dangling_tails(&here, &[below], above, &zones, &boxes, fa)
        };
        // The wall is 0.7 mm on: the end is extended onto it.
        let with_wall = layer(0, vec![line_below.clone(), wall]);
        let t = run(&with_wall, Some(&empty));
        assert_eq!(t.len(), 1);
        let q = t[0].after.expect("anchored");
        assert!(t[0].line == 100 && t[0].cut.is_empty() && t[0].before.is_none());
        assert!(q[0] > 11.3 && q[0] < 12.0 && q[1].abs() < 1e-9, "{q:?}");
        // No wall: nothing to anchor on, nothing above rests on it: cut back to X ~10.
        let bare = layer(0, vec![line_below]);
        let t = run(&bare, Some(&empty));
        assert_eq!(t.len(), 1);
        let (a, b) = t[0].cut[0];
        assert!(
            (b - 9.3).abs() < 1e-9 && a > 7.8 && a < 8.3,
            "{:?}",
            t[0].cut
        );
        // A strand of the layer above crosses the hanging end: it stays.
        let above = layer(
            2,
            vec![bead(Role::Infill, &[[10.9, -2.0], [10.9, 2.0]], 200)],
        );
        assert!(run(&bare, Some(&above)).is_empty());
        // The layer above unknown: no cut.
        assert!(run(&bare, None).is_empty());
    }

    #[test]
    fn speeds_of_zero_in_the_file_fall_back_to_the_defaults() {
        // 0 passes the ranges as the slicer's "auto": loops at 1 mm/s added 2877 s to a
        // print instead of 42.
        let config =
            SlicerConfig::parse(b"; bridge_speed = 0\n; travel_speed = 0\n; retract_speed = -0\n");
        let m = Motion::from_config(&config, &PoaSettings::default());
        assert_eq!(m.loop_speed, MmPerS(25.0));
        assert_eq!(m.perimeter_speed, MmPerS(25.0));
        assert_eq!(m.travel.travel_speed, MmPerS(150.0));
        assert_eq!(m.travel.retract_speed, MmPerS(35.0));
        let config = SlicerConfig::parse(b"; bridge_speed = 40\n; travel_speed = 180\n");
        let m = Motion::from_config(&config, &PoaSettings::default());
        assert_eq!(m.loop_speed, MmPerS(40.0));
        assert_eq!(m.travel.travel_speed, MmPerS(180.0));
    }

    #[test]
    fn short_loops_are_slowed_to_their_cooling_time_within_limits() {
        let v = MmPerS(25.0);
        let floor = COOLING_FLOOR;
        assert_eq!(slowed_for_cooling(v, 50.0, 1.0, floor), v);
        assert_eq!(slowed_for_cooling(v, 10.0, 1.0, floor), MmPerS(10.0));
        assert_eq!(slowed_for_cooling(v, 2.0, 1.0, floor), COOLING_FLOOR);
        assert_eq!(slowed_for_cooling(v, 10.0, 0.0, floor), v);
        assert_eq!(slowed_for_cooling(v, 2.0, 1.0, MmPerS(12.0)), MmPerS(12.0));
        // A floor above the loop speed slows nothing.
        assert_eq!(slowed_for_cooling(v, 2.0, 1.0, MmPerS(40.0)), v);
    }

    #[test]
    fn loops_are_slowed_no_further_than_the_slicer_s_own_cooling_floor() {
        // PrusaSlicer's min_print_speed, OrcaSlicer's slow_down_min_speed, Cura's
        // cool_min_speed; never under poa's 5 mm/s; the setting overrides; 0 states none.
        let floor = |text: &[u8], set: Option<f64>| {
            let settings = PoaSettings {
                min_loop_speed: set,
                ..PoaSettings::default()
            };
            Motion::from_config(&SlicerConfig::parse(text), &settings).cooling_floor
        };
        assert_eq!(floor(b"; min_print_speed = 10\n", None), MmPerS(10.0));
        assert_eq!(floor(b"; slow_down_min_speed = 20\n", None), MmPerS(20.0));
        let cura = b";SETTING_3 {\"global_quality\": \"[values]\\\\ncool_min_speed = 12\\\\n\"}\n";
        assert_eq!(floor(cura, None), MmPerS(12.0));
        // Cura writes only what the user changed: left out, its default.
        assert_eq!(
            floor(b";Generated with Cura_SteamEngine 4.13.0\n", None),
            MmPerS(10.0)
        );
        assert_eq!(floor(b"; min_print_speed = 2\n", None), COOLING_FLOOR);
        assert_eq!(floor(b"; min_print_speed = 0\n", None), COOLING_FLOOR);
        assert_eq!(floor(b"", None), COOLING_FLOOR);
        assert_eq!(floor(b"; min_print_speed = 10\n", Some(3.0)), MmPerS(3.0));
    }

    #[test]
    fn footer_statistics_follow_the_rewrite() {
        let block = b"G1 E-.8\n; filament used [mm] = 2060.39\n; filament used [cm3] = 4.96\n\
; filament used [g] = 6.15\n; filament cost = 0.16\n; estimated printing time (normal mode) = 35m 49s\n\
; estimated printing time (silent mode) = 1h 0m 59s\n; filament used [mm] = 1.0, 2.0\n";
        let area = crate::layers::filament_area(1.75);
        let out = update_footer(block, 33.0, 36.4, area, 1.24);
        let text = String::from_utf8(out).unwrap();
        assert!(text.contains("; filament used [mm] = 2093.39\n"), "{text}");
        assert!(text.contains("; filament used [cm3] = 5.04\n"), "{text}");
        assert!(text.contains("; filament used [g] = 6.25\n"), "{text}");
        assert!(text.contains("; filament cost = 0.16\n"), "{text}");
        assert!(text.contains("(normal mode) = 36m 25s\n"), "{text}");
        assert!(text.contains("(silent mode) = 1h 1m 35s\n"), "{text}");
        assert!(text.contains("= 1.0, 2.0\n"), "lists are left alone");
        assert!(text.starts_with("G1 E-.8\n"));
    }

    #[test]
    fn footer_times_carry_across_units() {
        let area = crate::layers::filament_area(1.75);
        let block = b"; estimated printing time (normal mode) = 1d 23h 59m 30s\n\
; estimated printing time (silent mode) = 59s\n";
        let text = String::from_utf8(update_footer(block, 0.0, 45.0, area, 1.24)).unwrap();
        assert!(text.contains("(normal mode) = 2d 0h 0m 15s\n"), "{text}");
        assert!(text.contains("(silent mode) = 1m 44s\n"), "{text}");
    }

    #[test]
    fn strands_get_the_intervals_a_clip_gives() {
        use crate::geometry::clip_lines;
        use geo::polygon;
        // A 10 mm square zone with a 2 mm square hole.
        let zone = MultiPolygon::new(vec![polygon!(
            exterior: [(x: 0.0, y: 0.0), (x: 10.0, y: 0.0), (x: 10.0, y: 10.0), (x: 0.0, y: 10.0)],
            interiors: [[(x: 4.0, y: 4.0), (x: 6.0, y: 4.0), (x: 6.0, y: 6.0), (x: 4.0, y: 6.0)]],
        )]);
        let index = RingIndex::new(&zone);
        let cases: [&[[f64; 2]]; 6] = [
            &[[1.0, 1.0], [3.0, 2.0]],
            &[[11.0, 1.0], [12.0, 9.0]],
            &[[4.5, 4.5], [5.5, 5.5]],
            &[[-1.0, 5.0], [11.0, 5.0]],
            &[[-1.0, 1.0], [5.0, 1.0], [5.0, 12.0]],
            &[[2.0, 2.0], [8.0, 8.0]],
        ];
        for pts in cases {
            let by_clip: f64 = clip_lines(&[pts.to_vec()], &zone, true)
                .iter()
                .map(|p| polyline_length(p))
                .sum();
            let by_intervals: f64 = inside_intervals(pts, &index)
                .iter()
                .map(|(a, b)| b - a)
                .sum();
            assert!(
                (by_clip - by_intervals).abs() < 1e-6,
                "{pts:?}: {by_clip} vs {by_intervals}"
            );
        }
        // Crossing the whole square through the hole: 4 + 4 mm inside.
        let iv = inside_intervals(&[[-1.0, 5.0], [11.0, 5.0]], &index);
        assert_eq!(iv.len(), 2, "{iv:?}");
        assert!(
            (iv[0].0 - 1.0).abs() < 1e-6 && (iv[1].1 - 11.0).abs() < 1e-6,
            "{iv:?}"
        );
    }
}
