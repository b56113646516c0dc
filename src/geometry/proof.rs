//! A cheap proof that a layer prints nothing over air, tried before any polygon work.
//!
//! Input: a layer, and a [`Support`] of the layer below and of the layer itself (its strands'
//! centerlines in a grid). Output: `true` only when [`super::find_regions`] is certain to find
//! no region on the layer; `false` says nothing (the exact path then runs). It never changes a
//! result: the areas the exact path would build are never needed when it holds.
//!
//! Why it is sound. A layer's printed area A is its outline footprint F (strands buffered by
//! half their width, [`super::area`]) with some holes closed, plus the footprints of stray
//! interior strands. The exact path finds a region only where A reaches beyond G, the area
//! below grown by the tolerance. The proof shows A lies inside G:
//! 1. F lies inside G: every outline strand of the layer, sampled every [`STEP`], lies within
//!    `tolerance + (w_below - w) / 2` of an outline strand below, less the polygon error of
//!    the arcs and half a sample step (so the whole bead between samples is covered); a
//!    segment that fails so is sampled again every [`FINE_STEP`] before the layer fails.
//! 2. No stray footprints: every interior strand (infill) starts, ends and has its middle point
//!    on an outline strand of its own layer, so it lies inside the layer's area and adds
//!    nothing.
//! 3. G has holes only inside the loops that wall the part's holes: below, every external
//!    perimeter is a closed loop (one path, or a run of pieces each starting where the
//!    last ended: Arachne splits a loop where its width changes), inside at most one other
//!    (a hole's wall in a part's outline; a post standing in a hole is left to the exact
//!    path), loops are far apart from each other and from themselves across air (no loop
//!    comes back within reach of itself farther along; loops facing each other across the
//!    part, as the walls between a perforated plate's holes, may come as close as they
//!    like: growing closes no air there), and a bead runs beside every external perimeter
//!    on its material side (inside an outline, outside a hole's wall) within a gap no hole
//!    of `min_hole` fits in: an inner perimeter, or the external perimeter of the loop
//!    beside it (two holes close together) or of its own far along (a thin fin's far side),
//!    never its own pieces nearby, which on a curve lie on its material side. So no hole
//!    of the area below is walled by an external perimeter but the part's holes (the only
//!    holes left open), and growing it closes none.
//! 4. Every hole of G lies in a hole of this layer's area that stays open: a loop of this
//!    layer follows the hole's wall below within the tolerance, nothing is printed inside it
//!    and a disc of `min_hole` fits in it ([`holes_kept`]).
//!
//! Layers whose roles do not tell walls from infill, with support material or overhang
//! perimeters, are left to the exact path. The residue: a notch in a wall narrower than the
//! reach and bottle-shaped (closed at its mouth by the growth), of less than
//! [`NOTCH_AREA`] mm2, could hide a region that small; regions that small are below the
//! default minimum area.

use crate::layers::{Layer, LayerKind, Role};

use super::area::{interior, is_outline, midpoints, wall_joins};
use super::regions::DetectOptions;

/// Sample spacing along a strand (mm).
pub const STEP: f64 = 0.1;
/// Sample spacing along an external loop for its flanking perimeter (mm).
const FLANK_STEP: f64 = 0.4;
/// A flanking gap small enough not to look for a smaller one (mm).
const FLANK_OK: f64 = 0.5;
/// Reach (mm) of the proof's queries for flanking perimeters and infill ends, and the least
/// reach of the search for loops close to each other ([`Support::reach`]).
const CELL: f64 = 1.0;
/// Farthest the search for loops close to each other reaches (mm): a layer below whose loops
/// would need more (a wide nozzle with a tolerance set wide) is left to the exact path.
const MAX_REACH: f64 = 2.0;
/// The grid's cell (mm). Twice the reach: a query reads 1 to 4 cells, about as many
/// strands as with cells of the reach, and a plate's grid has a quarter of the cells to
/// clear and count (a layer of 16 stems: 22 000 cells of 1 mm).
const GRID_CELL: f64 = 2.0;
/// Chord error of a footprint's arcs per mm of radius: geo's buffer draws a cap or join
/// with chords of 0.35 rad, 1 - cos(0.175) of the radius inside the circle.
const ARC_SHARE: f64 = 0.0153;
/// Chord error of Clipper's round offsets (`ARC_TOLERANCE`) and its integer rounding.
const OFFSET_SLACK: f64 = 0.006;
/// Arc length (mm) along an external loop beyond which the loop must not come back near
/// itself (a hairpin shorter than this closes no hole bigger than [`NOTCH_AREA`]).
const LOOP_ARC: f64 = 4.0;
/// The largest notch the loop rule can miss: one of perimeter `LOOP_ARC` plus its mouth.
pub const NOTCH_AREA: f64 = 0.6;

/// A segment of a strand's centerline with its half width.
#[derive(Debug, Clone, Copy)]
pub(super) struct Seg {
    pub(super) a: [f64; 2],
    pub(super) b: [f64; 2],
    pub(super) half: f64,
    pub(super) role: Role,
    pub(super) loop_at: Option<LoopAt>,
}

/// Index of the external loop a segment belongs to, and its arc position (mm) there.
pub(super) type LoopAt = (u32, f64);

/// Squared distance from `q` to the segment's centreline.
pub(super) fn dist2(q: [f64; 2], s: &Seg) -> f64 {
    let (dx, dy) = (s.b[0] - s.a[0], s.b[1] - s.a[1]);
    let (px, py) = (q[0] - s.a[0], q[1] - s.a[1]);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        ((px * dx + py * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let (ex, ey) = (px - t * dx, py - t * dy);
    ex * ex + ey * ey
}

/// The point of the segment's centreline nearest `q`.
fn closest(q: [f64; 2], s: &Seg) -> [f64; 2] {
    let (dx, dy) = (s.b[0] - s.a[0], s.b[1] - s.a[1]);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        (((q[0] - s.a[0]) * dx + (q[1] - s.a[1]) * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    [s.a[0] + t * dx, s.a[1] + t * dy]
}

/// Segments bucketed by grid cell (a dense grid over their box, filled by counting): each
/// segment is cut into pieces no longer than a cell and entered in the cells of each piece's
/// box.
#[derive(Debug, Default)]
pub(super) struct Grid {
    segs: Vec<Seg>,
    origin: [f64; 2],
    /// 1 / cell size (1/mm).
    inv_cell: f64,
    nx: usize,
    ny: usize,
    /// Cell `i` holds `items[start[i]..start[i + 1]]`.
    start: Vec<u32>,
    items: Vec<u32>,
}

/// Most cells a grid holds: a plate's box in 1 mm cells is far fewer; a hostile file's box
/// gets bigger cells instead of more memory.
const MAX_CELLS: f64 = 4.0e6;

impl Grid {
    pub(super) fn new(segs: Vec<Seg>) -> Grid {
        let mut b = [
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ];
        for s in &segs {
            for q in [s.a, s.b] {
                b = [
                    b[0].min(q[0]),
                    b[1].min(q[1]),
                    b[2].max(q[0]),
                    b[3].max(q[1]),
                ];
            }
        }
        if segs.is_empty() || !b.iter().all(|v| v.is_finite()) {
            return Grid::default();
        }
        let (w, h) = (b[2] - b[0], b[3] - b[1]);
        let cell = GRID_CELL.max(((w + GRID_CELL) * (h + GRID_CELL) / MAX_CELLS).sqrt());
        let nx = (w / cell).floor() as usize + 1;
        let ny = (h / cell).floor() as usize + 1;
        let mut grid = Grid {
            segs,
            origin: [b[0], b[1]],
            inv_cell: 1.0 / cell,
            nx,
            ny,
            start: Vec::new(),
            items: Vec::new(),
        };
        // Two passes over the pieces: count per cell, then fill.
        let mut cells: Vec<(u32, u32)> = Vec::with_capacity(grid.segs.len() * 2);
        for (i, s) in grid.segs.iter().enumerate() {
            let n = pieces(seg_len(s) / cell);
            let mut prev = (usize::MAX, usize::MAX, usize::MAX, usize::MAX);
            for k in 0..n {
                let p0 = lerp(s.a, s.b, k as f64 / n as f64);
                let p1 = lerp(s.a, s.b, (k + 1) as f64 / n as f64);
                let (x0, x1) = (grid.col(p0[0].min(p1[0])), grid.col(p0[0].max(p1[0])));
                let (y0, y1) = (grid.row(p0[1].min(p1[1])), grid.row(p0[1].max(p1[1])));
                for ix in x0..=x1 {
                    for iy in y0..=y1 {
                        // Consecutive pieces share cells: enter each once.
                        if ix >= prev.0 && ix <= prev.1 && iy >= prev.2 && iy <= prev.3 {
                            continue;
                        }
                        cells.push(((iy * nx + ix) as u32, i as u32));
                    }
                }
                prev = (x0, x1, y0, y1);
            }
        }
        (grid.start, grid.items) = super::buckets(nx * ny, &cells);
        grid
    }

    fn col(&self, x: f64) -> usize {
        super::cell_of_inv(x, self.origin[0], self.inv_cell, self.nx)
    }

    fn row(&self, y: f64) -> usize {
        super::cell_of_inv(y, self.origin[1], self.inv_cell, self.ny)
    }

    /// Calls `f` with every segment entered in a cell within `reach` of `q`, until it
    /// returns true; whether it did.
    pub(super) fn any_near(
        &self,
        q: [f64; 2],
        reach: f64,
        mut f: impl FnMut(&Seg) -> bool,
    ) -> bool {
        self.any_near_at(q, reach, |_, s| f(s))
    }

    /// [`Grid::any_near`], `f` given each segment's index in `segs` too.
    fn any_near_at(&self, q: [f64; 2], reach: f64, mut f: impl FnMut(usize, &Seg) -> bool) -> bool {
        if self.segs.is_empty() || !(q[0].is_finite() && q[1].is_finite()) {
            return false;
        }
        let (x0, x1) = (self.col(q[0] - reach), self.col(q[0] + reach));
        let (y0, y1) = (self.row(q[1] - reach), self.row(q[1] + reach));
        for iy in y0..=y1 {
            for ix in x0..=x1 {
                let c = iy * self.nx + ix;
                let (from, to) = (self.start[c] as usize, self.start[c + 1] as usize);
                for &i in &self.items[from..to] {
                    if f(i as usize, &self.segs[i as usize]) {
                        return true;
                    }
                }
            }
        }
        false
    }
}

/// `x` rounded up, at least 1 (`as` saturates: NaN gives 1, infinity the most there is).
/// Without SSE4.1 in the baseline target, `f64::ceil` is a call into libm, and this runs
/// for every segment the proof reads.
fn pieces(x: f64) -> usize {
    let n = x as usize;
    if (n as f64) < x {
        n.saturating_add(1)
    } else {
        n.max(1)
    }
}

fn lerp(a: [f64; 2], b: [f64; 2], t: f64) -> [f64; 2] {
    [a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t]
}

/// Points every [`STEP`] or closer along a segment, both ends included.
fn samples(a: [f64; 2], b: [f64; 2]) -> impl Iterator<Item = [f64; 2]> {
    samples_every(a, b, STEP)
}

/// Points every `step` or closer along a segment, both ends included.
fn samples_every(a: [f64; 2], b: [f64; 2], step: f64) -> impl Iterator<Item = [f64; 2]> {
    let len = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt();
    let n = pieces(len / step);
    (0..=n).map(move |k| lerp(a, b, k as f64 / n as f64))
}

/// What a layer offers the proof: its outline strands in a grid, and what is known of its
/// external loops.
#[derive(Debug, Default)]
pub struct Support {
    /// The layer tells walls from infill and has no support material or overhang perimeter.
    plain: bool,
    grid: Grid,
    /// Closest approach (mm) across air of an external loop to another loop or to itself
    /// farther along than [`LOOP_ARC`], searched up to `reach` (the value when none is
    /// nearer).
    approach: f64,
    /// How far (mm) `approach` was searched: the reach the layer above needs, from this
    /// layer's widest external perimeter and the tolerance at its height, at least [`CELL`]
    /// (a 0.6 mm nozzle at 0.3 mm layers needs 1.4 mm).
    reach: f64,
    /// Whether the external loops are closed, their boxes apart and each flanked by a bead
    /// within the gap given (mm, [`Support::flanks`]); `None` when they are not.
    flank_gap: Option<f64>,
    widest_external: f64,
    /// Half the widest outline strand (mm).
    widest_half: f64,
    /// The external loops, in the order of the layer's external perimeters.
    loops: Vec<Loop>,
}

/// Pairs of meeting boxes [`nesting`] examines per loop at most.
const PAIRS_PER_LOOP: usize = 16;

/// An external perimeter as a closed polyline: one path, or a run of pieces each starting
/// where the last ended (Arachne splits a loop where its width changes).
#[derive(Debug)]
struct Loop {
    bbox: [f64; 4],
    pts: Vec<[f64; 2]>,
    /// Half the width (mm) of each segment `pts[i]..pts[i + 1]`.
    halves: Vec<f64>,
    /// Half its narrowest and its widest piece's width (mm).
    half_min: f64,
    half_max: f64,
    /// It lies inside another loop: it walls a hole of the part, whose material is outside
    /// it ([`nesting`]).
    hole: bool,
}

impl Loop {
    /// Whether `q` lies inside the loop (even-odd rule on the polyline, closed).
    fn contains(&self, q: [f64; 2]) -> bool {
        let b = &self.bbox;
        if q[0] < b[0] || q[0] > b[2] || q[1] < b[1] || q[1] > b[3] {
            return false;
        }
        let pts = &self.pts;
        let mut inside = false;
        let n = pts.len();
        for i in 0..n {
            let (a, c) = (pts[i], pts[(i + 1) % n]);
            if (a[1] > q[1]) != (c[1] > q[1]) {
                let x = a[0] + (q[1] - a[1]) / (c[1] - a[1]) * (c[0] - a[0]);
                if x > q[0] {
                    inside = !inside;
                }
            }
        }
        inside
    }

    /// Twice the signed area of the polygon the loop closes (positive counter-clockwise).
    /// `1.0` when the part's material lies left of the way the loop runs (counter-clockwise
    /// round a part, clockwise round a hole), else `-1.0`.
    fn material_side(&self) -> f64 {
        if (self.signed_area2() > 0.0) != self.hole {
            1.0
        } else {
            -1.0
        }
    }

    fn signed_area2(&self) -> f64 {
        let n = self.pts.len();
        (0..n)
            .map(|i| {
                let (a, c) = (self.pts[i], self.pts[(i + 1) % n]);
                a[0] * c[1] - c[0] * a[1]
            })
            .sum()
    }

    /// The centroid of the polygon the loop closes (`None` when it has no area).
    fn centroid(&self) -> Option<[f64; 2]> {
        let n = self.pts.len();
        let (mut a2, mut cx, mut cy) = (0.0, 0.0, 0.0);
        for i in 0..n {
            let (p, q) = (self.pts[i], self.pts[(i + 1) % n]);
            let cross = p[0] * q[1] - q[0] * p[1];
            a2 += cross;
            cx += (p[0] + q[0]) * cross;
            cy += (p[1] + q[1]) * cross;
        }
        let c = [cx / (3.0 * a2), cy / (3.0 * a2)];
        (a2.abs() > 1e-9 && c[0].is_finite() && c[1].is_finite()).then_some(c)
    }

    /// Distance from `q` to the loop's centreline.
    fn distance(&self, q: [f64; 2]) -> f64 {
        let n = self.pts.len();
        (0..n)
            .map(|i| {
                let (a, b) = (self.pts[i], self.pts[(i + 1) % n]);
                dist2(
                    q,
                    &Seg {
                        a,
                        b,
                        half: 0.0,
                        role: Role::ExternalPerimeter,
                        loop_at: None,
                    },
                )
            })
            .fold(f64::INFINITY, f64::min)
            .sqrt()
    }
}

/// Marks the loops that lie inside another ([`Loop::hole`]); `false` when a loop lies
/// inside two (a post in a part's hole: the proof leaves it to the exact path), or when
/// more pairs of boxes meet than [`PAIRS_PER_LOOP`] a loop (loops strewn over each other's
/// boxes: the exact path's work anyway). Loops far apart (as [`Support::approach`] then
/// checks) are nested when one's box holds the other's and one point of the other lies
/// inside it.
fn nesting(loops: &mut [Loop]) -> bool {
    let mut budget = PAIRS_PER_LOOP * loops.len() + 1000;
    let mut order: Vec<usize> = (0..loops.len()).collect();
    order.sort_unstable_by(|&a, &b| loops[a].bbox[0].total_cmp(&loops[b].bbox[0]));
    let mut depth = vec![0u8; loops.len()];
    let holds = |o: &Loop, i: &Loop| {
        o.bbox[0] <= i.bbox[0]
            && o.bbox[1] <= i.bbox[1]
            && o.bbox[2] >= i.bbox[2]
            && o.bbox[3] >= i.bbox[3]
            && i.pts.first().is_some_and(|&q| o.contains(q))
    };
    for (k, &i) in order.iter().enumerate() {
        for &j in &order[k + 1..] {
            let (a, b) = (&loops[i], &loops[j]);
            if b.bbox[0] > a.bbox[2] {
                break;
            }
            if b.bbox[1] > a.bbox[3] || a.bbox[1] > b.bbox[3] {
                continue;
            }
            budget = match budget.checked_sub(1) {
                Some(left) => left,
                None => return false,
            };
            if holds(a, b) {
                depth[j] += 1;
            } else if holds(b, a) {
                depth[i] += 1;
            }
            if depth[i] > 1 || depth[j] > 1 {
                return false;
            }
        }
    }
    if depth.iter().any(|&d| d > 1) {
        return false;
    }
    for (l, d) in loops.iter_mut().zip(depth) {
        l.hole = d == 1;
    }
    true
}

impl Support {
    pub fn new(layer: &Layer, opts: &DetectOptions) -> Support {
        if layer.kind != LayerKind::Layer || !plain(layer) {
            return Support::default();
        }
        let joins = wall_joins(layer);
        let (loop_polys, run_of, loops_ok) = external_loops(layer);
        let outline = layer
            .paths
            .iter()
            .zip(&run_of)
            .filter(|(p, _)| is_outline(p.role))
            .map(|(p, &run)| (p, run))
            .chain(joins.iter().map(|p| (p, None)));
        let mut segs = Vec::new();
        for (p, run) in outline {
            let finite = p.points.iter().all(|q| {
                q[0].abs() < 1e6 && q[1].abs() < 1e6 && q[0].is_finite() && q[1].is_finite()
            });
            if !(finite && p.width > 0.0 && p.width < 50.0) {
                return Support::default();
            }
            let (loop_id, mut s_at) = match run {
                Some((id, at)) => (Some(id), at),
                None => (None, 0.0),
            };
            for w in p.points.windows(2) {
                let len = ((w[1][0] - w[0][0]).powi(2) + (w[1][1] - w[0][1]).powi(2)).sqrt();
                segs.push(Seg {
                    a: w[0],
                    b: w[1],
                    half: p.width / 2.0,
                    role: p.role,
                    loop_at: loop_id.map(|id| (id, s_at)),
                });
                s_at += len;
            }
        }
        let widest_external = layer
            .paths
            .iter()
            .filter(|p| p.role == Role::ExternalPerimeter)
            .map(|p| p.width)
            .fold(0.0, f64::max);
        let widest_half = segs.iter().map(|s| s.half).fold(0.0, f64::max);
        let grid = Grid::new(segs);
        // What `why_not` asks of the layer above at the same height, and a little more.
        let need = widest_external + 2.0 * opts.tolerance_at(layer.height) + 0.06;
        let mut sup = Support {
            plain: true,
            grid,
            approach: f64::INFINITY,
            reach: if need.is_finite() {
                need.clamp(CELL, MAX_REACH)
            } else {
                CELL
            },
            flank_gap: None,
            widest_external,
            widest_half,
            loops: loop_polys,
        };
        if loops_ok && nesting(&mut sup.loops) {
            // Both searches read the outline's grid and skip the strands they do not want:
            // building a grid of each kind cost more than the skipping.
            let loop_len: Vec<f64> = sup
                .loops
                .iter()
                .map(|l| super::polyline_length(&l.pts))
                .collect();
            sup.flank_gap = Support::flanks(&sup.loops, &loop_len, &sup.grid, opts.area.min_hole);
            let sides: Vec<f64> = sup.loops.iter().map(Loop::material_side).collect();
            sup.approach = Support::closest_approach(&sup.grid, &loop_len, &sides, sup.reach);
        }
        sup
    }

    /// The widest gap between an external perimeter and the bead beside it (an inner
    /// perimeter, another loop's external perimeter, or its own far along), if every piece
    /// of every external loop has one on its material side (inside a part's
    /// outer loop, outside a hole's) farther than the wall zone (`w_e / 2 + 0.1` from its
    /// centerline, [`super::area`]'s walled test) reaches. Sampled every [`FLANK_STEP`]: a
    /// point between samples is at most half a step from one, so the gap grows and the reach
    /// shrinks by that much. The side matters: a loop whose inner perimeter runs outside it
    /// walls an empty inside, a hole of the area below that a roof above would close.
    fn flanks(loops: &[Loop], loop_len: &[f64], outline: &Grid, min_hole: f64) -> Option<f64> {
        let mut widest = 0.0f64;
        for (id, l) in loops.iter().enumerate() {
            // A part's outline too small to hold a hole of the area needs no flank: every
            // hole of its footprint inside it lies in its box less the bead's inner reach,
            // narrower than `min_hole`, and is filled (a pin or a fin printed as one loop with
            // nothing inside).
            let side = (l.bbox[2] - l.bbox[0]).min(l.bbox[3] - l.bbox[1]);
            if !l.hole && side - 2.0 * l.half_min * (1.0 - ARC_SHARE) < min_hole {
                continue;
            }
            // Material lies left of the way the loop runs when it runs counter-clockwise
            // round a part or clockwise round a hole.
            let side = l.material_side();
            let total = loop_len.get(id).copied().unwrap_or(0.0);
            let mut last: Option<usize> = None;
            let mut at = 0.0;
            for (w, &he) in l.pts.windows(2).zip(&l.halves) {
                let normal = [-(w[1][1] - w[0][1]) * side, (w[1][0] - w[0][0]) * side];
                for q in samples_every(w[0], w[1], FLANK_STEP) {
                    let q_at = at + dist(w[0], q);
                    let gap = |s: &Seg| {
                        // An inner perimeter, or the external perimeter of a loop beside
                        // this one (the walls between a perforated plate's holes, one bead
                        // each side), or of this loop come back far along (a thin fin's far
                        // side); not the loop's own pieces nearby, which on a curve lie on
                        // its material side at any distance.
                        match s.loop_at {
                            Some((sid, s_at)) if sid as usize == id => {
                                let near = arc_gap(q_at, q_at, s_at, s_at + seg_len(s), total);
                                if near <= LOOP_ARC {
                                    return None;
                                }
                            }
                            _ if s.role != Role::Perimeter && s.role != Role::ExternalPerimeter => {
                                return None
                            }
                            _ => {}
                        }
                        let c = closest(q, s);
                        if (c[0] - q[0]) * normal[0] + (c[1] - q[1]) * normal[1] < 0.0 {
                            return None;
                        }
                        let d = ((c[0] - q[0]).powi(2) + (c[1] - q[1]).powi(2)).sqrt();
                        (d + s.half - FLANK_STEP / 2.0 > he + 0.11)
                            .then(|| d - he - s.half + FLANK_STEP / 2.0)
                    };
                    // The perimeter beside the last sample, or the next piece along it,
                    // usually serves this one too; any gap under FLANK_OK will do (only the
                    // widest one is kept).
                    let mut best = f64::INFINITY;
                    if let Some(j) = last {
                        for k in [j, j + 1] {
                            if let Some(g) = outline.segs.get(k).and_then(gap) {
                                if g < best {
                                    best = g;
                                    last = Some(k);
                                }
                            }
                            if best <= FLANK_OK {
                                break;
                            }
                        }
                    }
                    if best > FLANK_OK {
                        outline.any_near_at(q, CELL, |k, s| {
                            if let Some(g) = gap(s) {
                                if g < best {
                                    best = g;
                                    last = Some(k);
                                }
                            }
                            false
                        });
                    }
                    if !best.is_finite() {
                        return None;
                    }
                    widest = widest.max(best);
                }
                at += dist(w[0], w[1]);
            }
        }
        Some(widest)
    }

    /// Whether `q` lies in a part: inside an odd number of external loops (inside a part's
    /// outer loop and none of its holes').
    fn in_material(&self, q: [f64; 2]) -> bool {
        self.loops.iter().filter(|l| l.contains(q)).count() % 2 == 1
    }

    /// See [`Support::approach`]: exact segment-to-segment distances between the external
    /// loops' segments, up to `reach`, across air: two pieces that each lie wholly on the
    /// other's material side ([`across_material`]) face each other across the part, where
    /// growing the area closes nothing (the walls between a perforated plate's holes).
    fn closest_approach(outline: &Grid, loop_len: &[f64], sides: &[f64], reach: f64) -> f64 {
        let mut closest = reach;
        for s in &outline.segs {
            let Some((id, at)) = s.loop_at else { continue };
            let slen = seg_len(s);
            let mid = lerp(s.a, s.b, 0.5);
            let sb = seg_box(s);
            outline.any_near(mid, slen / 2.0 + closest, |t| {
                let Some((tid, tat)) = t.loop_at else {
                    return false;
                };
                // The boxes' gap bounds the distance from below: most strands the grid's
                // cells hold lie farther than the closest approach found.
                let tb = seg_box(t);
                let gx = (sb[0].max(tb[0]) - sb[2].min(tb[2])).max(0.0);
                let gy = (sb[1].max(tb[1]) - sb[3].min(tb[3])).max(0.0);
                if gx * gx + gy * gy >= closest * closest {
                    return false;
                }
                if tid == id {
                    let total = loop_len.get(id as usize).copied().unwrap_or(0.0);
                    if arc_gap(at, at + slen, tat, tat + seg_len(t), total) <= LOOP_ARC {
                        return false;
                    }
                }
                // Crossing pieces are 0 apart, and never across the part.
                let nearest = nearest_points(s, t);
                let d = nearest.map_or(0.0, |(p, q)| dist(p, q));
                if d < closest {
                    let side = |id: u32| sides.get(id as usize).copied().unwrap_or(0.0);
                    if !nearest.is_some_and(|pq| across_material(s, side(id), t, side(tid), pq)) {
                        closest = d;
                    }
                }
                false
            });
        }
        closest
    }
}

/// Whether `s` and `t` face each other across the part, given their nearest points `p` (on
/// `s`) and `q` (on `t`, [`nearest_points`]): `q` lies on `s`'s material side (`side_s`, as
/// [`Loop::material_side`]) and `p` on `t`'s. Where air lies between two loops (a slot, a
/// bay's mouth, the gap between two parts), the banks come closest at a pair of points that
/// are the nearest points of their pieces (the distance between two segments is convex in
/// their parameters), and the way across leaves one bank into air: strictly on the air side
/// of the piece there, or of one of the two pieces meeting there at a corner, so that pair
/// fails this. A point on a piece's line counts as material (two aligned square holes'
/// corners face along their sides); touching pieces as air.
fn across_material(s: &Seg, side_s: f64, t: &Seg, side_t: f64, (p, q): Pair) -> bool {
    if dist(p, q) <= 1e-9 {
        return false;
    }
    let beyond = |u: &Seg, side: f64, r: [f64; 2]| {
        side * ((u.b[0] - u.a[0]) * (r[1] - u.a[1]) - (u.b[1] - u.a[1]) * (r[0] - u.a[0])) >= 0.0
    };
    beyond(s, side_s, q) && beyond(t, side_t, p)
}

/// A point of one segment and a point of another.
type Pair = ([f64; 2], [f64; 2]);

/// The nearest points of `s` and `t` (on `s`, on `t`); `None` where they cross.
fn nearest_points(s: &Seg, t: &Seg) -> Option<Pair> {
    if segments_cross(s.a, s.b, t.a, t.b) {
        return None;
    }
    [
        (s.a, closest(s.a, t)),
        (s.b, closest(s.b, t)),
        (closest(t.a, s), t.a),
        (closest(t.b, s), t.b),
    ]
    .into_iter()
    .min_by(|x, y| d2(x.0, x.1).total_cmp(&d2(y.0, y.1)))
}

fn d2(p: [f64; 2], q: [f64; 2]) -> f64 {
    (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)
}

fn dist(p: [f64; 2], q: [f64; 2]) -> f64 {
    d2(p, q).sqrt()
}

fn seg_box(s: &Seg) -> [f64; 4] {
    [
        s.a[0].min(s.b[0]),
        s.a[1].min(s.b[1]),
        s.a[0].max(s.b[0]),
        s.a[1].max(s.b[1]),
    ]
}

fn seg_len(s: &Seg) -> f64 {
    ((s.b[0] - s.a[0]).powi(2) + (s.b[1] - s.a[1]).powi(2)).sqrt()
}

/// Arc distance between the intervals [a0, a1] and [b0, b1] of a loop of length `total`.
fn arc_gap(a0: f64, a1: f64, b0: f64, b1: f64, total: f64) -> f64 {
    if a1 >= b0 && b1 >= a0 {
        return 0.0;
    }
    let d = if a1 < b0 { b0 - a1 } else { a0 - b1 };
    let round = if a1 < b0 {
        total - b1 + a0
    } else {
        total - a1 + b0
    };
    d.min(round.max(0.0))
}

/// Distance between two segments.
fn seg_dist(s: &Seg, t: &Seg) -> f64 {
    nearest_points(s, t).map_or(0.0, |(p, q)| dist(p, q))
}

fn segments_cross(a: [f64; 2], b: [f64; 2], c: [f64; 2], d: [f64; 2]) -> bool {
    let orient = |p: [f64; 2], q: [f64; 2], r: [f64; 2]| {
        (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0])
    };
    let (d1, d2) = (orient(c, d, a), orient(c, d, b));
    let (d3, d4) = (orient(a, b, c), orient(a, b, d));
    ((d1 > 0.0) != (d2 > 0.0)) && ((d3 > 0.0) != (d4 > 0.0))
}

/// Whether the layer's roles are the kind the proof reasons about: walls told apart, no
/// support material (its grids close holes of their own) and no overhang perimeters.
fn plain(layer: &Layer) -> bool {
    let mut external = false;
    for p in &layer.paths {
        match p.role {
            Role::ExternalPerimeter => external = true,
            Role::Support | Role::SupportInterface | Role::OverhangPerimeter => return false,
            _ => {}
        }
    }
    external
}

/// The layer's external perimeters as loops ([`Loop`], `hole` not yet known); for each of
/// the layer's paths, the loop it is a piece of and the arc length (mm) along the loop
/// where it starts; and whether every loop is closed (its two ends within its narrowest
/// piece's width, and at least four points).
fn external_loops(layer: &Layer) -> (Vec<Loop>, Vec<Option<LoopAt>>, bool) {
    let mut loops: Vec<Loop> = Vec::new();
    let mut run_of = vec![None; layer.paths.len()];
    let mut at = 0.0;
    for (i, p) in layer.paths.iter().enumerate() {
        if p.role != Role::ExternalPerimeter {
            continue;
        }
        let half = p.width / 2.0;
        let goes_on = i > 0
            && run_of[i - 1].is_some()
            && {
                let q = &layer.paths[i - 1];
                q.object == p.object
                    && matches!((q.points.last(), p.points.first()), (Some(e), Some(s)) if dist(*e, *s) <= 1e-6)
            };
        if !goes_on {
            loops.push(Loop {
                bbox: [0.0; 4],
                pts: p.points.first().copied().into_iter().collect(),
                halves: Vec::new(),
                half_min: half,
                half_max: half,
                hole: false,
            });
            at = 0.0;
        }
        let id = (loops.len() - 1) as u32;
        let Some(l) = loops.last_mut() else { continue };
        run_of[i] = Some((id, at));
        at += super::polyline_length(&p.points);
        l.half_min = l.half_min.min(half);
        l.half_max = l.half_max.max(half);
        for &q in p.points.iter().skip(1) {
            l.pts.push(q);
            l.halves.push(half);
        }
    }
    let mut ok = true;
    for l in &mut loops {
        l.bbox = points_box(&l.pts);
        let ends = l.pts.first().zip(l.pts.last());
        ok &= l.pts.len() >= 4 && ends.is_some_and(|(a, b)| dist(*a, *b) <= 2.0 * l.half_min);
    }
    (loops, run_of, ok)
}

fn points_box(points: &[[f64; 2]]) -> [f64; 4] {
    points.iter().fold(
        [
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ],
        |b, q| {
            [
                b[0].min(q[0]),
                b[1].min(q[1]),
                b[2].max(q[0]),
                b[3].max(q[1]),
            ]
        },
    )
}

/// Whether `layer` is certain to have no region over the layer below (see the module doc).
/// `below` and `here` are the [`Support`]s of the layer below and of `layer`.
pub fn supported(below: &Support, layer: &Layer, here: &Support, opts: &DetectOptions) -> bool {
    why_not(below, layer, here, opts).is_none()
}

/// `None` when [`supported`] holds, else the first condition that failed and where.
pub fn why_not(
    below: &Support,
    layer: &Layer,
    here: &Support,
    opts: &DetectOptions,
) -> Option<String> {
    if !below.plain || !here.plain || layer.kind != LayerKind::Layer {
        return Some("roles: walls not told apart, support or overhang perimeters".into());
    }
    // Numeric slivers of the booleans are dropped only by a minimum area and width.
    if opts.min_area < 1e-3 || opts.min_width() < 1e-3 {
        return Some("minimum area or width zero".into());
    }
    let tol = opts.tolerance_at(layer.height);
    // 3. The area below has no holes, and growing it closes none.
    let Some(gap) = below.flank_gap else {
        return Some("below: external loops open, nested or not flanked".into());
    };
    if gap >= opts.area.min_hole - 0.02 {
        return Some(format!(
            "below: gap {gap:.3} mm beside an external perimeter"
        ));
    }
    let reach = below.widest_external + 2.0 * tol + 0.05;
    if reach >= below.reach || below.approach <= reach {
        return Some(format!("below: loops {:.3} mm apart", below.approach));
    }
    // 4. Every hole of the area below stays a hole of this layer's area.
    if let Some(why) = holes_kept(below, layer, here, opts, tol) {
        return Some(why);
    }
    // 1. The outline lies within the tolerance of the outline below.
    let under = &below.grid.segs;
    // The strand below that covered the last sample: a wall rising straight is covered
    // piece by piece by the strand below it, so the next sample is tried against it and the
    // pieces beside it along its path before the grid is asked (which strand answers never
    // matters: a sample fails only when no strand below covers it).
    let mut last: Option<usize> = None;
    for s in &here.grid.segs {
        let covers_at = |q: [f64; 2], t: &Seg| {
            let need = tol - OFFSET_SLACK - ARC_SHARE * t.half - STEP / 2.0 + t.half - s.half;
            need > 0.0 && dist2(q, t) <= need * need
        };
        for q in samples(s.a, s.b) {
            let covers = |t: &Seg| covers_at(q, t);
            let mut found = last.and_then(|j| {
                [j, j + 1, j.wrapping_sub(1)]
                    .into_iter()
                    .find(|&k| under.get(k).is_some_and(covers))
            });
            if found.is_none() {
                below.grid.any_near_at(q, tol + below.widest_half, |k, t| {
                    let ok = covers(t);
                    if ok {
                        found = Some(k);
                    }
                    ok
                });
            }
            match found {
                // The distance to a segment is convex along a line: a strand below that
                // covers this sample and the segment's end covers all between (a wall that
                // rises straight is proven in two queries a segment, not one every STEP).
                Some(k) if covers_at(s.b, &under[k]) => {
                    last = Some(k);
                    break;
                }
                Some(k) => last = Some(k),
                // A wall that wobbles between layers by nearly the tolerance fails the
                // coarse samples' slack: its segment is sampled finely before the layer
                // goes to the exact path.
                None if covered_finely(below, s, tol) => break,
                None => {
                    return Some(format!(
                        "outline at {:.3},{:.3} off the outline below",
                        q[0], q[1]
                    ))
                }
            }
        }
    }
    // 2. Every interior strand's first, middle and last points lie in the layer's area: on
    // its outline, or inside one of its external loops, whose inside holes are all closed
    // (the loops are flanked by inner perimeters, as 3. checks below).
    let here_flanked = here
        .flank_gap
        .is_some_and(|g| g < opts.area.min_hole - 0.02);
    for p in layer.paths.iter().filter(|p| interior(p.role)) {
        let n = p.points.len();
        if n == 0 {
            continue;
        }
        for q in [p.points[0], p.points[n / 2], p.points[n - 1]] {
            let inside = here.grid.any_near(q, CELL, |t| {
                let r = t.half * (1.0 - ARC_SHARE) - 0.002;
                r > 0.0 && dist2(q, t) <= r * r
            }) || (here_flanked && here.in_material(q));
            if !inside {
                return Some(format!(
                    "infill point {:.3},{:.3} off the outline",
                    q[0], q[1]
                ));
            }
        }
    }
    None
}

/// Sample spacing (mm) of [`covered_finely`].
const FINE_STEP: f64 = 0.01;

/// Rule 1 for one segment of this layer's outline, sampled every [`FINE_STEP`] (the slack
/// for the bead between samples shrinks with it) and each sample tried on every strand
/// below within reach.
fn covered_finely(below: &Support, s: &Seg, tol: f64) -> bool {
    let base = tol - OFFSET_SLACK - FINE_STEP / 2.0 - s.half;
    samples_every(s.a, s.b, FINE_STEP).all(|q| {
        below.grid.any_near(q, tol + below.widest_half, |t| {
            let need = base + t.half * (1.0 - ARC_SHARE);
            need > 0.0 && dist2(q, t) <= need * need
        })
    })
}

/// How far (mm) another strand's footprint may reach past a hole's wall into the hole, more
/// than half the wall's width: what a strand that ends on the wall (the join from the inner
/// perimeter to the loop's start) adds to the chords of the two footprints there.
const BAND_SLACK: f64 = 1e-3;

/// Least minimum width (mm) for the hole rule: wider than those slivers.
const MIN_WIDTH_HOLES: f64 = 0.01;

/// `None` when every hole of the area below (the inside of a hole's loop there, shrunk by
/// the wall and the tolerance: `K`) lies in a hole of this layer's area that the area
/// model keeps open, else where one does not. A hole's loop `H` of this layer keeps `K`
/// open when
/// - a point `x` lies inside both loops, more than `min_hole / 2` inside `K` and inside
///   `H`'s hole past the band its bead covers (`w / 2`, and [`BAND_SLACK`]);
/// - `H` runs within the tolerance of the loop below everywhere, so it never enters `K`:
///   `K`, connected (the loops below are far from themselves, [`Support::approach`]), lies
///   inside `H` with `x`;
/// - nothing of this layer lies in `H`'s hole but in that band: no interior strand's
///   segment midpoint (the area model's evidence of infill) and no footprint of another
///   outline strand farther in. Then the hole of the area round `x` is walled all along by
///   `H`, holds a disc of `min_hole` round `x` and no infill: it stays open
///   ([`super::area`]'s rule), and whatever of `K` is not covered by this layer's outline
///   (rule 1 keeps it out of the grown area below) lies in it.
///
/// The residue: pieces of `K` cut off in a notch of either loop (as rule 3's), and slivers
/// between the chords of two beads' arcs in the band (thousandths of a millimetre wide,
/// below the minimum width the proof asks for).
fn holes_kept(
    below: &Support,
    layer: &Layer,
    here: &Support,
    opts: &DetectOptions,
    tol: f64,
) -> Option<String> {
    let min_hole = opts.area.min_hole;
    let mut clear: Vec<Option<bool>> = Vec::new();
    let mut mids: Option<Vec<[f64; 2]>> = None;
    // This layer's holes' loops by the left side of their boxes, and the widest box: those
    // whose box can meet one below lie in a run of them (a plate pierced by a thousand
    // holes asks a column, not all).
    let mut above: Vec<usize> = (0..here.loops.len())
        .filter(|&k| here.loops[k].hole)
        .collect();
    above.sort_unstable_by(|&a, &b| here.loops[a].bbox[0].total_cmp(&here.loops[b].bbox[0]));
    let widest = above
        .iter()
        .map(|&k| here.loops[k].bbox[2] - here.loops[k].bbox[0])
        .fold(0.0, f64::max);
    for (id, lb) in below.loops.iter().enumerate().filter(|(_, l)| l.hole) {
        // No point of the inside lies farther from the loop than half its box's narrower
        // side: nothing of the hole is left once the tolerance has grown the wall.
        // Pieces of a loop may differ in width: the bead's reach is taken at the narrowest
        // where it bounds what the wall covers, at the widest where it bounds how deep a
        // point lies.
        let r_b = lb.half_min * (1.0 - ARC_SHARE) + tol - OFFSET_SLACK;
        let r_deep = lb.half_max * (1.0 - ARC_SHARE) + tol - OFFSET_SLACK;
        let side = (lb.bbox[2] - lb.bbox[0]).min(lb.bbox[3] - lb.bbox[1]);
        if side <= 2.0 * r_b {
            continue;
        }
        // Nor is a hole the area model closes below: a point inside the loop more than `d`
        // from it lies more than `d` inside the loop's box on every side (the ray from it
        // out of the box's side crosses the loop), so every hole of the footprint in it,
        // its edge at least the bead's half width (less the arcs' chord error) from the
        // centreline, has a box narrower than `min_hole` and is filled
        // ([`super::area`]'s rule): no hole of the grown area lies there.
        if side - 2.0 * lb.half_min * (1.0 - ARC_SHARE) < min_hole {
            continue;
        }
        // The disc round `x` must not fit in a notch.
        if std::f64::consts::FRAC_PI_4 * min_hole * min_hole <= NOTCH_AREA {
            return Some("minimum hole too small to tell a hole from a notch".into());
        }
        let from = above.partition_point(|&k| here.loops[k].bbox[0] < lb.bbox[0] - widest);
        let to = above.partition_point(|&k| here.loops[k].bbox[0] <= lb.bbox[2]);
        let kept = here.flank_gap.is_some()
            && above[from..to.max(from)].iter().any(|&k| {
                let lh = &here.loops[k];
                let band = lh.half_max + BAND_SLACK;
                if here.approach <= 2.0 * band
                    || opts.min_width() < MIN_WIDTH_HOLES
                    || !boxes_meet(&lh.bbox, &lb.bbox)
                {
                    return false;
                }
                let deep = |x: [f64; 2]| {
                    lb.contains(x)
                        && lh.contains(x)
                        && lb.distance(x) > r_deep + min_hole / 2.0
                        && lh.distance(x) > band + min_hole / 2.0 + 0.01
                };
                if !lh.centroid().into_iter().chain(lb.centroid()).any(deep) {
                    return false;
                }
                if !follows(lh, &below.grid, id as u32, r_b - STEP / 2.0) {
                    return false;
                }
                if clear.is_empty() {
                    clear = vec![None; here.loops.len()];
                }
                let mids = mids.get_or_insert_with(|| midpoints(layer, interior));
                *clear[k].get_or_insert_with(|| hole_clear(mids, here, k))
            });
        if !kept {
            let at = lb.pts.first().copied().unwrap_or_default();
            return Some(format!(
                "below: hole at {:.3},{:.3} not kept open",
                at[0], at[1]
            ));
        }
    }
    None
}

fn boxes_meet(a: &[f64; 4], b: &[f64; 4]) -> bool {
    a[0] <= b[2] && b[0] <= a[2] && a[1] <= b[3] && b[1] <= a[3]
}

/// Whether every point of `l`'s centreline lies within `r` of loop `id` of `below`'s grid.
fn follows(l: &Loop, below: &Grid, id: u32, r: f64) -> bool {
    if r <= 0.0 {
        return false;
    }
    let n = l.pts.len();
    let mut last: Option<usize> = None;
    (0..n).all(|i| {
        let (a, b) = (l.pts[i], l.pts[(i + 1) % n]);
        let near = |q: [f64; 2], t: &Seg| {
            t.loop_at.is_some_and(|(tid, _)| tid == id) && dist2(q, t) <= r * r
        };
        for q in samples(a, b) {
            let mut found = last.filter(|&k| below.segs.get(k).is_some_and(|t| near(q, t)));
            if found.is_none() {
                below.any_near_at(q, r, |k, t| {
                    let ok = near(q, t);
                    if ok {
                        found = Some(k);
                    }
                    ok
                });
            }
            match found {
                // Convex along the segment: one strand covering both ends covers it all.
                Some(k) if near(b, &below.segs[k]) => {
                    last = Some(k);
                    return true;
                }
                Some(k) => last = Some(k),
                None => return false,
            }
        }
        true
    })
}

/// Whether nothing of `layer` but loop `k` of `here` lies inside it, but what its own bead
/// covers: no midpoint of an interior strand's segment (`mids`, sorted by x: the area
/// model's own evidence of infill, [`midpoints`]),
/// and no footprint of another outline strand reaching farther than half the loop's width
/// (and [`BAND_SLACK`]) past its centreline, nor crossing it.
fn hole_clear(mids: &[[f64; 2]], here: &Support, k: usize) -> bool {
    let h = &here.loops[k];
    let in_box = |q: [f64; 2], m: f64| {
        q[0] >= h.bbox[0] - m
            && q[0] <= h.bbox[2] + m
            && q[1] >= h.bbox[1] - m
            && q[1] <= h.bbox[3] + m
    };
    // The area model closes a hole holding a midpoint of an interior strand's segment.
    let from = mids.partition_point(|q| q[0] < h.bbox[0]);
    let to = mids.partition_point(|q| q[0] <= h.bbox[2]).max(from);
    if mids[from..to]
        .iter()
        .any(|&q| in_box(q, 0.0) && h.contains(q))
    {
        return false;
    }
    let own = |t: &Seg| t.loop_at.is_some_and(|(id, _)| id as usize == k);
    // The join that closes the loop's seam ([`wall_joins`]) is the polygon's closing side.
    let seam = (h.pts.last().copied(), h.pts.first().copied());
    let closes = |t: &Seg| (Some(t.a), Some(t.b)) == seam;
    // The outline strands near the loop's box, from the grid's cells round it.
    let reach = here.widest_half + h.half_max + BAND_SLACK;
    let centre = [(h.bbox[0] + h.bbox[2]) / 2.0, (h.bbox[1] + h.bbox[3]) / 2.0];
    let half_side = ((h.bbox[2] - h.bbox[0]) / 2.0).max((h.bbox[3] - h.bbox[1]) / 2.0);
    let mut near: Vec<usize> = Vec::new();
    here.grid.any_near_at(centre, half_side + reach, |i, _| {
        near.push(i);
        false
    });
    near.sort_unstable();
    near.dedup();
    near.into_iter().all(|i| {
        let s = &here.grid.segs[i];
        let m = s.half + h.half_max + BAND_SLACK;
        if own(s)
            || closes(s)
            || !(in_box(s.a, m)
                || in_box(s.b, m)
                || in_box(lerp(s.a, s.b, 0.5), m + seg_len(s) / 2.0))
        {
            return true;
        }
        // A strand that ends on the loop (a join to its start) touches it: its ends are
        // pulled in by a ten-thousandth so that touching is not crossing.
        let len = seg_len(s);
        let cut = if len > 1e-3 { 1e-4 / len } else { 0.0 };
        let t = Seg {
            a: lerp(s.a, s.b, cut),
            b: lerp(s.a, s.b, 1.0 - cut),
            ..*s
        };
        if [t.a, t.b].iter().any(|&q| h.contains(q)) {
            return false;
        }
        // How far the strand's bead reaches past a piece of the loop beyond that piece's own
        // bead (the pieces of an Arachne loop differ in width).
        let mut past = f64::NEG_INFINITY;
        let crossed = here.grid.any_near(lerp(t.a, t.b, 0.5), len / 2.0 + m, |u| {
            if !own(u) {
                return false;
            }
            if segments_cross(t.a, t.b, u.a, u.b) {
                return true;
            }
            past = past.max(s.half - seg_dist(&t, u) - u.half);
            false
        });
        !crossed && past <= BAND_SLACK - 1e-4
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{find_regions, printed_area};
    use crate::layers::testing::layer;
    use crate::layers::Path;

    fn path(role: Role, pts: &[[f64; 2]]) -> Path {
        crate::layers::testing::path(role, 0.45, pts)
    }

    fn square(c: f64, half: f64) -> Vec<[f64; 2]> {
        let (a, b) = (c - half, c + half);
        vec![[a, a], [b, a], [b, b], [a, b], [a, a]]
    }

    /// A closed polygon of `n` sides round `c`, its corners `r` from it.
    fn circle(c: [f64; 2], r: f64, n: usize) -> Vec<[f64; 2]> {
        (0..=n)
            .map(|k| {
                let a = std::f64::consts::TAU * (k % n) as f64 / n as f64;
                [c[0] + r * a.cos(), c[1] + r * a.sin()]
            })
            .collect()
    }

    /// Numbers uniform in [0, 1), the same run for the same `seed`.
    fn uniform(seed: u64) -> impl FnMut() -> f64 {
        let mut next = crate::layers::testing::xorshift(seed);
        move || (next() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// A square part centred at (10, 10): external loop of half side `half`, inner loops
    /// `perimeters - 1`, and infill lines across the inside when `infill`.
    fn part(half: f64, perimeters: usize, infill: bool) -> Vec<Path> {
        let mut v = vec![path(Role::ExternalPerimeter, &square(10.0, half))];
        for k in 1..perimeters {
            v.push(path(Role::Perimeter, &square(10.0, half - 0.43 * k as f64)));
        }
        if infill {
            let inner = half - 0.43 * perimeters as f64;
            let mut y = 10.0 - inner + 0.5;
            while y < 10.0 + inner {
                v.push(path(Role::Infill, &[[10.0 - inner, y], [10.0 + inner, y]]));
                y += 2.0;
            }
        }
        v
    }

    /// The proof's verdict, checked against the exact path: when it holds, the exact path
    /// finds nothing.
    fn verdict(below: Vec<Path>, here: Vec<Path>) -> Option<String> {
        let (b, h) = (layer(4, below), layer(5, here));
        let opts = DetectOptions::default();
        let why = why_not(
            &Support::new(&b, &opts),
            &h,
            &Support::new(&h, &opts),
            &opts,
        );
        if why.is_none() {
            let (ab, ah) = (printed_area(&b, &opts.area), printed_area(&h, &opts.area));
            assert!(find_regions(&ab, &h, &ah, &opts).is_empty());
        }
        why
    }

    #[test]
    fn pieces_round_up() {
        for (x, n) in [
            (0.0, 1),
            (0.3, 1),
            (1.0, 1),
            (1.0000001, 2),
            (2.5, 3),
            (7.0, 7),
        ] {
            assert_eq!(pieces(x), n, "{x}");
        }
        assert_eq!(pieces(f64::NAN), 1);
        assert_eq!(pieces(-3.0), 1);
        assert_eq!(pieces(f64::INFINITY), usize::MAX);
    }

    #[test]
    fn the_slacks_cover_the_polygon_errors_they_stand_for() {
        let buffer_chord = 1.0 - (crate::geometry::area::ROUND_ANGLE / 2.0).cos();
        assert!(ARC_SHARE >= buffer_chord, "{buffer_chord}");
        let offset = crate::geometry::ARC_TOLERANCE + 2.0 / crate::geometry::CLIPPER_SCALE;
        assert!(OFFSET_SLACK >= offset, "{offset}");
    }

    #[test]
    fn a_straight_wall_is_proven() {
        assert_eq!(verdict(part(5.0, 2, true), part(5.0, 2, true)), None);
        // Moved out by less than the tolerance: still held up.
        assert_eq!(verdict(part(5.0, 2, true), part(5.1, 2, true)), None);
    }

    #[test]
    fn an_outline_beyond_the_tolerance_is_not() {
        let why = verdict(part(5.0, 2, true), part(5.3, 2, true));
        assert!(why.is_some_and(|w| w.contains("off the outline below")));
    }

    #[test]
    fn a_single_wall_below_leaves_the_inside_to_the_exact_path() {
        // One wall, no infill: the inside below is a real hole, a roof above is over air.
        let mut roof = part(5.0, 1, false);
        for k in 0..20 {
            let y = 5.5 + 0.45 * k as f64;
            roof.push(path(Role::SolidInfill, &[[4.8, y], [15.2, y]]));
        }
        let why = verdict(part(5.0, 1, false), roof);
        assert!(why.is_some_and(|w| w.contains("flanked")));
    }

    #[test]
    fn a_round_single_wall_is_not_its_own_flank() {
        // A single round wall with nothing inside: its own pieces a few tenths along lie on
        // its material side, yet its inside is a hole, and a roof over it is over air.
        let wall = vec![path(
            Role::ExternalPerimeter,
            &circle([10.0, 10.0], 3.0, 96),
        )];
        let mut roof = wall.clone();
        for k in 0..13 {
            let y = 7.3 + 0.45 * k as f64;
            let dx = (2.8f64.powi(2) - (y - 10.0).powi(2)).max(0.0).sqrt();
            roof.push(path(Role::SolidInfill, &[[10.0 - dx, y], [10.0 + dx, y]]));
        }
        let opts = DetectOptions::default();
        let (b, h) = (layer(4, wall.clone()), layer(5, roof.clone()));
        let (ab, ah) = (printed_area(&b, &opts.area), printed_area(&h, &opts.area));
        assert!(!find_regions(&ab, &h, &ah, &opts).is_empty());
        assert!(verdict(wall, roof).is_some());
    }

    #[test]
    fn a_pin_printed_as_one_loop_needs_no_flank() {
        // A pin of 1.2 mm beside the part, its one loop round nothing: no hole of `min_hole`
        // fits inside it.
        let mut v = part(5.0, 2, true);
        v.push(path(Role::ExternalPerimeter, &square(20.0, 0.6)));
        assert_eq!(verdict(v.clone(), v.clone()), None);
        // A wider one is a hollow: its inside is a hole the layer above may roof.
        let mut w = part(5.0, 2, true);
        w.push(path(Role::ExternalPerimeter, &square(20.0, 1.2)));
        assert!(verdict(w.clone(), w).is_some_and(|why| why.contains("flanked")));
    }

    #[test]
    fn a_loop_printed_in_pieces_of_different_widths_is_proven() {
        // Arachne splits a loop where its width changes: each side of the square here.
        let sq = square(10.0, 5.0);
        let mut v: Vec<Path> = sq
            .windows(2)
            .zip([0.42, 0.45, 0.5, 0.45])
            .map(|(w, width)| crate::layers::testing::path(Role::ExternalPerimeter, width, w))
            .collect();
        v.extend(part(5.0, 3, true).into_iter().skip(1));
        assert_eq!(verdict(v.clone(), v), None);
    }

    /// A 10 x 10 part with two square holes of 3 mm side whose walls run back to back
    /// between them (one bead each, no perimeter between: a perforated plate's thin walls),
    /// inner perimeters round their other three sides, infill round them; a lid over the
    /// first hole when `lid`.
    fn twin_holes(lid: bool) -> Vec<Path> {
        let mut v = part(5.0, 2, false);
        for x in [10.0 - 1.725, 10.0 + 1.725] {
            let hole: Vec<[f64; 2]> = square(0.0, 1.5)
                .iter()
                .map(|q| [q[0] + x, q[1] + 10.0])
                .collect();
            v.push(path(Role::ExternalPerimeter, &hole));
        }
        v.push(path(
            Role::Perimeter,
            &[[9.775, 8.07], [6.345, 8.07], [6.345, 11.93], [9.775, 11.93]],
        ));
        v.push(path(
            Role::Perimeter,
            &[
                [10.225, 8.07],
                [13.655, 8.07],
                [13.655, 11.93],
                [10.225, 11.93],
            ],
        ));
        for k in 0..10 {
            let y = 5.5 + k as f64;
            if (y - 10.0f64).abs() < 1.93 {
                v.push(path(Role::Infill, &[[5.43, y], [6.345, y]]));
                v.push(path(Role::Infill, &[[13.655, y], [14.57, y]]));
            } else {
                v.push(path(Role::Infill, &[[5.43, y], [14.57, y]]));
            }
        }
        if lid {
            for k in 0..7 {
                let y = 8.65 + 0.45 * k as f64;
                v.push(path(Role::SolidInfill, &[[6.9, y], [9.65, y]]));
            }
        }
        v
    }

    #[test]
    fn walls_back_to_back_flank_each_other() {
        assert_eq!(verdict(twin_holes(false), twin_holes(false)), None);
        let why = verdict(twin_holes(false), twin_holes(true));
        assert!(why.is_some_and(|w| w.contains("not kept open")));
    }

    /// A 10 x 10 part round a square hole of half side `hole` (both walled by two
    /// perimeters), with infill rows on either side of the hole when `infill`.
    fn tube(hole: f64, infill: bool) -> Vec<Path> {
        let mut v = part(5.0, 2, false);
        v.push(path(Role::ExternalPerimeter, &square(10.0, hole)));
        v.push(path(Role::Perimeter, &square(10.0, hole + 0.43)));
        if infill {
            let (inner, edge) = (5.0 - 0.86, hole + 0.86);
            let mut y: f64 = 10.0 - inner + 0.5;
            while y < 10.0 + inner {
                if (y - 10.0).abs() < edge {
                    v.push(path(Role::Infill, &[[10.0 - inner, y], [10.0 - edge, y]]));
                    v.push(path(Role::Infill, &[[10.0 + edge, y], [10.0 + inner, y]]));
                } else {
                    v.push(path(Role::Infill, &[[10.0 - inner, y], [10.0 + inner, y]]));
                }
                y += 1.0;
            }
        }
        v
    }

    #[test]
    fn a_hole_rising_straight_is_proven() {
        assert_eq!(verdict(tube(2.0, true), tube(2.0, true)), None);
        assert_eq!(verdict(tube(2.0, false), tube(2.0, false)), None);
        // Widening by less than the tolerance: the wall still rests on the one below.
        assert_eq!(verdict(tube(2.0, true), tube(2.1, true)), None);
        // A pin hole the area model closes below (0.75 mm between the bead's inner edges).
        assert_eq!(verdict(tube(0.6, true), tube(0.6, true)), None);
        assert_eq!(verdict(tube(0.6, false), tube(0.6, false)), None);
    }

    #[test]
    fn a_roof_over_a_hole_is_left_to_the_exact_path() {
        let mut roofed = tube(2.0, true);
        for k in 0..9 {
            let y = 8.2 + 0.45 * k as f64;
            roofed.push(path(Role::SolidInfill, &[[7.8, y], [12.2, y]]));
        }
        let why = verdict(tube(2.0, true), roofed);
        assert!(why.is_some_and(|w| w.contains("not kept open")));
        // A roof strand bent into the hole, its three sampled points on the wall.
        let mut bent = tube(2.0, true);
        bent.push(path(
            Role::SolidInfill,
            &[
                [8.0, 8.0],
                [9.0, 9.5],
                [10.0, 8.0],
                [11.0, 9.5],
                [12.0, 8.0],
            ],
        ));
        let why = verdict(tube(2.0, true), bent);
        assert!(why.is_some_and(|w| w.contains("not kept open")));
    }

    #[test]
    fn a_hole_closing_in_is_left_to_the_exact_path() {
        // Narrowed by 0.3 mm a side: more than the tolerance, an overhang inside the hole.
        assert!(verdict(tube(2.0, true), tube(1.7, true)).is_some());
        // A wall strand of this layer inside the hole (a post starting there).
        let mut post = tube(2.0, true);
        post.push(path(Role::Perimeter, &square(10.0, 0.5)));
        let why = verdict(tube(2.0, true), post);
        assert!(why.is_some_and(|w| w.contains("not kept open")));
    }

    /// A 12 x 12 part round a polygonal hole of radius `r` centred at `c` (`n` sides, turned
    /// by `phase`, run backwards when `reverse`), walls and infill as a slicer lays them, and
    /// `extra`: 1 a roof over the hole, 2 a wall inside it, 3 one infill line across it.
    fn holed(c: [f64; 2], r: f64, n: usize, phase: f64, reverse: bool, extra: u32) -> Vec<Path> {
        let ring = |r: f64| -> Vec<[f64; 2]> {
            let mut v: Vec<[f64; 2]> = (0..=n)
                .map(|k| {
                    let a = phase + std::f64::consts::TAU * (k % n) as f64 / n as f64;
                    [c[0] + r * a.cos(), c[1] + r * a.sin()]
                })
                .collect();
            if reverse {
                v.reverse();
            }
            v
        };
        let mut v = part(6.0, 2, false);
        v.push(path(Role::ExternalPerimeter, &ring(r)));
        v.push(path(Role::Perimeter, &ring(r + 0.43)));
        let (lo, hi, edge) = (10.0 - 5.14, 10.0 + 5.14, r + 0.86);
        let mut y: f64 = lo + 0.5;
        while y < hi {
            let dy = y - c[1];
            if dy.abs() < edge {
                let dx = (edge * edge - dy * dy).sqrt();
                for (a, b) in [(lo, c[0] - dx), (c[0] + dx, hi)] {
                    if b > a {
                        v.push(path(Role::Infill, &[[a, y], [b, y]]));
                    }
                }
            } else {
                v.push(path(Role::Infill, &[[lo, y], [hi, y]]));
            }
            y += 1.0;
        }
        match extra {
            1 => {
                let mut y = c[1] - r;
                while y < c[1] + r {
                    v.push(path(Role::SolidInfill, &[[c[0] - r, y], [c[0] + r, y]]));
                    y += 0.45;
                }
            }
            2 => v.push(path(Role::Perimeter, &ring(r * 0.5))),
            3 => v.push(path(
                Role::Infill,
                &[[c[0] - r - 0.43, c[1]], [c[0] + r + 0.43, c[1]]],
            )),
            _ => {}
        }
        v
    }

    #[test]
    fn random_holes_never_hide_a_region_from_the_proof() {
        // `verdict` asserts that the exact path finds nothing wherever the proof holds.
        let mut rand = uniform(0x2545_f491_4f6c_dd1d);
        let mut proven = 0;
        for _ in 0..1000 {
            let n = 6 + (rand() * 40.0) as usize;
            let (r, phase) = (0.6 + rand() * 3.4, rand());
            let below = holed([10.0, 10.0], r, n, phase, rand() < 0.5, 0);
            // The hole above: as below, or moved, grown, shrunk, turned, roofed, walled in.
            let change = rand();
            let (mut c, mut rh, mut ph) = ([10.0, 10.0], r, phase);
            if change < 0.3 {
                c = [10.0 + (rand() - 0.5) * 0.6, 10.0 + (rand() - 0.5) * 0.6];
            } else if change < 0.6 {
                rh = (r + (rand() - 0.5) * 0.8).max(0.3);
            } else if change < 0.7 {
                ph = rand();
            }
            let extra = if rand() < 0.3 {
                1 + (rand() * 3.0) as u32
            } else {
                0
            };
            let here = holed(c, rh, n, ph, rand() < 0.5, extra);
            if verdict(below, here).is_none() {
                proven += 1;
            }
        }
        // Enough cases proven for the check to mean something.
        assert!(proven > 200, "{proven}");
    }

    #[test]
    fn random_holes_and_parts_close_together_never_hide_a_region_from_the_proof() {
        // Holes 0.9 to 2.9 mm apart (across the part: each one's inner perimeter between
        // them) and a second part 0.2 to 1.8 mm away (across air), the layer above as below or with a hole
        // narrowing, a lid over a hole, the second part grown or moved: `verdict` asserts
        // that the exact path finds nothing wherever the proof holds.
        let mut rand = uniform(0x9e37_79b9_7f4a_7c15);
        let rect = |c: [f64; 2], h: [f64; 2]| {
            let (a, b) = ([c[0] - h[0], c[1] - h[1]], [c[0] + h[0], c[1] + h[1]]);
            vec![
                [a[0], a[1]],
                [b[0], a[1]],
                [b[0], b[1]],
                [a[0], b[1]],
                [a[0], a[1]],
            ]
        };
        let mut proven = 0;
        for _ in 0..1000 {
            // Holes in a row across the part, each gap drawn on its own.
            let mut holes: Vec<([f64; 2], [f64; 2])> = Vec::new();
            let mut x = 5.5;
            while holes.len() < 4 {
                // From holes the area model closes (under `min_hole` across the bead's
                // inner edges) to wide ones.
                let h = [0.5 + rand() * 1.5, 0.5 + rand() * 2.0];
                let c = [x + h[0], 10.0 + (rand() - 0.5) * 2.0];
                if c[0] + h[0] > 14.5 {
                    break;
                }
                holes.push((c, h));
                x = c[0] + h[0] + 0.9 + rand() * 2.0;
            }
            let gap = 0.2 + rand() * 1.6;
            let layout = |holes: &[([f64; 2], [f64; 2])], other: [f64; 2], lid: Option<usize>| {
                let mut v = part(6.0, 2, false);
                for (c, h) in holes {
                    v.push(path(Role::ExternalPerimeter, &rect(*c, *h)));
                    v.push(path(Role::Perimeter, &rect(*c, [h[0] + 0.43, h[1] + 0.43])));
                }
                // The second part, beside the first across `gap`.
                v.push(path(Role::ExternalPerimeter, &rect(other, [2.0, 2.0])));
                v.push(path(Role::Perimeter, &rect(other, [1.57, 1.57])));
                if let Some(k) = lid {
                    let (c, h) = holes[k];
                    let mut y = c[1] - h[1];
                    while y <= c[1] + h[1] {
                        v.push(path(
                            Role::SolidInfill,
                            &[[c[0] - h[0], y], [c[0] + h[0], y]],
                        ));
                        y += 0.45;
                    }
                }
                v
            };
            let other = [16.0 + gap + 2.0, 10.0];
            let below = layout(&holes, other, None);
            let change = rand();
            let mut up = holes.clone();
            let (mut other_up, mut lid) = (other, None);
            if change < 0.25 && !up.is_empty() {
                let k = (rand() * up.len() as f64) as usize % up.len();
                let d = 0.2 + rand() * 0.6;
                up[k].1 = [(up[k].1[0] - d).max(0.2), (up[k].1[1] - d).max(0.2)];
            } else if change < 0.45 && !up.is_empty() {
                lid = Some((rand() * up.len() as f64) as usize % up.len());
            } else if change < 0.65 {
                other_up = [
                    other[0] - 0.2 - rand() * 0.5,
                    other[1] + (rand() - 0.5) * 0.4,
                ];
            }
            let here = layout(&up, other_up, lid);
            if verdict(below, here).is_none() {
                proven += 1;
            }
        }
        // Enough cases proven for the check to mean something (about one in eight).
        assert!(proven > 100, "{proven}");
    }

    #[test]
    fn random_round_parts_with_thin_and_pieced_walls_never_hide_a_region_from_the_proof() {
        // Round parts of 0.6 to 4.6 mm radius with one or two walls, the external one printed
        // in one to four pieces of their own widths (Arachne), with or without infill, a
        // second such part 0.1 to 1.6 mm away; above: the same, a roof over the inside, the
        // part grown or shrunk. `verdict` asserts that the exact path finds nothing wherever
        // the proof holds.
        let mut rand = uniform(0x2545_f491_4f6c_dd1d);
        struct Round {
            c: [f64; 2],
            r: f64,
            n: usize,
            walls: usize,
            infill: bool,
            cuts: Vec<(usize, f64)>,
        }
        let draw = |p: &Round, roof: bool, v: &mut Vec<Path>| {
            let pts = circle(p.c, p.r, p.n);
            let mut from = 0;
            for &(to, width) in &p.cuts {
                let to = to.clamp(from + 1, p.n);
                v.push(crate::layers::testing::path(
                    Role::ExternalPerimeter,
                    width,
                    &pts[from..=to],
                ));
                from = to;
                if from == p.n {
                    break;
                }
            }
            if from < p.n {
                v.push(path(Role::ExternalPerimeter, &pts[from..]));
            }
            for k in 1..p.walls {
                let r = p.r - 0.43 * k as f64;
                if r > 0.3 {
                    v.push(path(Role::Perimeter, &circle(p.c, r, p.n)));
                }
            }
            let inner = p.r - 0.43 * p.walls as f64;
            let rows = |role: Role, step: f64, v: &mut Vec<Path>| {
                let mut y = -inner + step / 2.0;
                while y < inner {
                    let dx = (inner * inner - y * y).max(0.0).sqrt();
                    if dx > 0.05 {
                        v.push(path(
                            role,
                            &[[p.c[0] - dx, p.c[1] + y], [p.c[0] + dx, p.c[1] + y]],
                        ));
                    }
                    y += step;
                }
            };
            if p.infill {
                rows(Role::Infill, 1.5, v);
            }
            if roof {
                rows(Role::SolidInfill, 0.45, v);
            }
        };
        let mut proven = 0;
        for _ in 0..1000 {
            let mut round = |c: [f64; 2]| {
                let n = 12 + (rand() * 80.0) as usize;
                let pieces = (rand() * 4.0) as usize;
                let mut cuts: Vec<(usize, f64)> = (0..pieces)
                    .map(|_| ((rand() * n as f64) as usize, 0.35 + rand() * 0.2))
                    .collect();
                cuts.sort_by_key(|c| c.0);
                Round {
                    c,
                    r: 0.6 + rand() * 4.0,
                    n,
                    walls: 1 + (rand() * 2.0) as usize,
                    infill: rand() < 0.5,
                    cuts,
                }
            };
            let a = round([10.0, 10.0]);
            let mut b = round([0.0, 10.0]);
            b.c[0] = 10.0 + a.r + b.r + 0.1 + rand() * 1.5;
            let below = {
                let mut v = Vec::new();
                draw(&a, false, &mut v);
                draw(&b, false, &mut v);
                v
            };
            let change = rand();
            let mut up = Round {
                cuts: a.cuts.clone(),
                ..a
            };
            let roof = change < 0.3;
            if (0.3..0.6).contains(&change) {
                up.r = (up.r + (rand() - 0.5) * 1.0).max(0.4);
            }
            let here = {
                let mut v = Vec::new();
                draw(&up, roof, &mut v);
                draw(&b, false, &mut v);
                v
            };
            if verdict(below, here).is_none() {
                proven += 1;
            }
        }
        assert!(proven > 50, "{proven}");
    }

    #[test]
    fn random_thin_bars_walled_by_one_loop_never_hide_a_region_from_the_proof() {
        // Bars 0.6 to 3.6 mm wide and 2 to 14 mm long, each a single external loop (its far
        // side the only bead on its material side) with nothing, a perimeter or infill
        // inside, two of them 0.1 to 2 mm apart; above: the same, a roof over the first's
        // inside, the first widened or narrowed. `verdict` asserts that the exact path finds
        // nothing wherever the proof holds.
        let mut rand = uniform(0x6a09_e667_f3bc_c908);
        let rect = |x0: f64, y0: f64, w: f64, l: f64| {
            vec![
                [x0, y0],
                [x0 + w, y0],
                [x0 + w, y0 + l],
                [x0, y0 + l],
                [x0, y0],
            ]
        };
        // (x, width, length, inside: 0 nothing, 1 a perimeter, 2 infill rows)
        let draw = |bars: &[(f64, f64, f64, u32)], roof: bool| {
            let mut v = Vec::new();
            for (k, &(x, w, l, inside)) in bars.iter().enumerate() {
                v.push(path(Role::ExternalPerimeter, &rect(x, 5.0, w, l)));
                let (iw, il) = (w - 0.86, l - 0.86);
                if inside == 1 && iw > 0.05 && il > 0.05 {
                    v.push(path(Role::Perimeter, &rect(x + 0.43, 5.43, iw, il)));
                }
                let rows = |role: Role, step: f64, v: &mut Vec<Path>| {
                    let mut y = 5.0 + step;
                    while y < 5.0 + l - step / 2.0 {
                        v.push(path(role, &[[x, y], [x + w, y]]));
                        y += step;
                    }
                };
                if inside == 2 {
                    rows(Role::Infill, 1.0, &mut v);
                }
                if roof && k == 0 {
                    rows(Role::SolidInfill, 0.45, &mut v);
                }
            }
            v
        };
        let mut proven = 0;
        for _ in 0..1000 {
            let bar = |x: f64, r: &mut dyn FnMut() -> f64| {
                (x, 0.6 + r() * 3.0, 2.0 + r() * 12.0, (r() * 3.0) as u32)
            };
            let a = bar(5.0, &mut rand);
            let gap = 0.1 + rand() * 1.9;
            let b = bar(a.0 + a.1 + gap, &mut rand);
            let below = draw(&[a, b], false);
            let change = rand();
            let mut up = a;
            if (0.3..0.6).contains(&change) {
                up.1 = (up.1 + (rand() - 0.5) * 1.0).max(0.5);
            }
            let here = draw(&[up, b], change < 0.3);
            if verdict(below, here).is_none() {
                proven += 1;
            }
        }
        assert!(proven > 50, "{proven}");
    }

    #[test]
    fn a_post_in_a_hole_is_left_to_the_exact_path() {
        let mut ring = tube(3.0, false);
        ring.push(path(Role::ExternalPerimeter, &square(10.0, 1.0)));
        ring.push(path(Role::Perimeter, &square(10.0, 0.57)));
        let why = verdict(ring.clone(), ring);
        assert!(
            why.as_ref().is_some_and(|w| w.contains("nested")),
            "{why:?}"
        );
    }

    #[test]
    fn a_wall_flanked_on_its_open_side_is_left_to_the_exact_path() {
        // The inner perimeter runs outside the external one: the loop's inside is empty, a
        // hole of the area below, and a roof over it is over air.
        let walls = vec![
            path(Role::ExternalPerimeter, &square(10.0, 5.0)),
            path(Role::Perimeter, &square(10.0, 5.43)),
        ];
        let mut roof = walls.clone();
        for k in 0..21 {
            let y = 5.5 + 0.45 * k as f64;
            roof.push(path(Role::SolidInfill, &[[5.0, y], [15.0, y]]));
        }
        let (b, h) = (layer(4, walls.clone()), layer(5, roof.clone()));
        let opts = DetectOptions::default();
        let (ab, ah) = (printed_area(&b, &opts.area), printed_area(&h, &opts.area));
        assert_eq!(find_regions(&ab, &h, &ah, &opts).len(), 1);
        // The perimeter outside does not flank it: none within reach inside.
        let why = verdict(walls, roof);
        assert!(why.as_ref().is_some_and(|w| w.contains("gap")), "{why:?}");
    }

    #[test]
    fn parts_close_together_are_left_to_the_exact_path() {
        // Two parts 0.35 mm apart: growing the area below could close the gap between them.
        let mut two = part(5.0, 2, true);
        for p in part(5.0, 2, true) {
            let mut q = p.clone();
            q.points.iter_mut().for_each(|c| c[0] += 10.8);
            two.push(q);
        }
        let why = verdict(two.clone(), two);
        assert!(why.as_ref().is_some_and(|w| w.contains("apart")), "{why:?}");
    }

    #[test]
    fn infill_outside_the_walls_is_left_to_the_exact_path() {
        let mut here = part(5.0, 2, true);
        here.push(path(Role::Infill, &[[30.0, 30.0], [32.0, 30.0]]));
        let why = verdict(part(5.0, 2, true), here);
        assert!(why.is_some_and(|w| w.contains("infill point")));
    }

    /// A part with two square holes whose walls run 0.75 mm apart (centrelines) across the
    /// part's material, each flanked by its inner perimeter.
    fn two_holes(infill_over_second: bool) -> Vec<Path> {
        let mut v = part(8.0, 2, false);
        for c in [8.125, 11.875] {
            let sq = |h: f64| {
                square(0.0, h)
                    .iter()
                    .map(|q| [q[0] + c, q[1] + 10.0])
                    .collect::<Vec<_>>()
            };
            v.push(path(Role::ExternalPerimeter, &sq(1.5)));
            v.push(path(Role::Perimeter, &sq(1.93)));
        }
        if infill_over_second {
            let mut y = 8.7;
            while y < 11.4 {
                v.push(path(Role::SolidInfill, &[[10.6, y], [13.15, y]]));
                y += 0.45;
            }
        }
        v
    }

    #[test]
    fn holes_close_together_across_the_part_are_proven() {
        // Growing the area closes nothing between them: the material is there already.
        assert_eq!(verdict(two_holes(false), two_holes(false)), None);
        // A lid over one of them is over air: left to the exact path.
        assert!(verdict(two_holes(false), two_holes(true)).is_some());
    }

    #[test]
    fn pieces_face_across_the_part_only_with_each_on_the_other_s_material_side() {
        let seg = |a: [f64; 2], b: [f64; 2]| Seg {
            a,
            b,
            half: 0.225,
            role: Role::ExternalPerimeter,
            loop_at: None,
        };
        // As the closest approach asks it.
        let across_material = |s: &Seg, side_s: f64, t: &Seg, side_t: f64| {
            nearest_points(s, t).is_some_and(|pq| super::across_material(s, side_s, t, side_t, pq))
        };
        // Two holes' walls (counter-clockwise round each: material on the right) facing
        // each other: the left hole's east side runs up, the right hole's west side down.
        let east = seg([9.6, 8.5], [9.6, 11.5]);
        let west = seg([10.4, 11.5], [10.4, 8.5]);
        assert!(across_material(&east, -1.0, &west, -1.0));
        // Two parts' outlines (counter-clockwise: material on the left) facing each other
        // across the air between them.
        let right_side = seg([9.6, 8.5], [9.6, 11.5]);
        let left_side = seg([10.4, 11.5], [10.4, 8.5]);
        assert!(!across_material(&right_side, 1.0, &left_side, 1.0));
        // Corners of aligned holes face along their sides: on the line counts as material.
        let bottom = seg([10.4, 8.5], [13.4, 8.5]);
        assert!(across_material(&east, -1.0, &bottom, -1.0));
        // One material side facing the other's air side (a post near a hole's wall's back).
        assert!(!across_material(&east, -1.0, &left_side, 1.0));
        // A long outline beside a short hole wall: judged at their nearest points, not by
        // the outline's far end (which lies beyond the hole wall's line).
        let outline = seg([5.0, 60.0], [5.0, 0.0]);
        let hole_west = seg([5.75, 10.2], [5.8, 9.8]);
        assert!(across_material(&outline, 1.0, &hole_west, -1.0));
        // Crossing pieces.
        assert!(!across_material(
            &seg([0.0, 0.0], [2.0, 2.0]),
            1.0,
            &seg([0.0, 2.0], [2.0, 0.0]),
            1.0
        ));
    }
}
