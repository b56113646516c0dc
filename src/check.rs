//! Deposition check: is every strand laid on material that already exists?
//!
//! Input: layers from [`crate::layers`] in file order. Output: for each strand sample, whether
//! it is supported, and per layer the supported / bridged / in-air lengths and the material
//! density.
//!
//! Model: strands are deposited in file order. A strand's bead is as wide as its E makes it
//! (flow model at its height), whatever a comment says. A point of a strand is supported when
//! material deposited before it (the layer below, or earlier strands of this layer, not the
//! strand's own last two widths of path unless the path has turned back since) lies within
//! `(0.5 - overlap_min) x width` of it. The first layer's beads count as squashed out by the
//! file's elephant-foot compensation ([`crate::layers::Layer::spread`]): the slicer draws
//! that layer's outline in by as much as it spreads, so the part's second layer stands on
//! its edge (a straight wall sliced with 0.4 mm of compensation read 119 mm in air).
//! Unsupported runs are *bridged* when supported points bound them on both sides and they span
//! at most `max_bridge` mm, else *in air*. Density = extruded volume / footprint area / height
//! (about 1.0 for a normal layer).
//!
//! [`EndSupport`] is the same model for the rewrite: where a strand's ends hang in air, and
//! where material close by would hold them.

use geo::Area;
use serde::Serialize;

use crate::geometry::{footprint_if_spread, nearest_on_segment};
use crate::layers::{flow_width, Layer, Path, Role};

/// Settings of the check.
#[derive(Debug, Clone, Serialize)]
pub struct CheckOptions {
    /// A point is supported when material lies within (0.5 - overlap_min) x its width.
    pub overlap_min: f64,
    /// Longest unsupported span counted as an intended bridge (mm).
    pub max_bridge: f64,
    /// Sampling step along strands (mm).
    pub step: f64,
}

impl Default for CheckOptions {
    fn default() -> Self {
        CheckOptions {
            overlap_min: 0.25,
            max_bridge: 10.0,
            step: 0.1,
        }
    }
}

/// A deposited segment: centreline and half width.
#[derive(Debug, Clone, Copy)]
struct Seg {
    a: [f64; 2],
    b: [f64; 2],
    half: f64,
}

impl Seg {
    fn distance(&self, p: [f64; 2]) -> f64 {
        let (_, c) = nearest_on_segment(p, self.a, self.b);
        (c[0] - p[0]).hypot(c[1] - p[1])
    }
}

/// Whether the path's own recent segment `o` holds the point `p` of the segment `a`-`b`
/// because the path turned back since laying it (headings more than 120 degrees apart): a
/// stroke laid back beside the one before it, joined to it by a short connector, rests on it
/// as it would after a travel. Only the bead's own trailing tail (same heading) waits the
/// two widths.
fn turned_back(o: &Seg, a: [f64; 2], b: [f64; 2], p: [f64; 2], reach: f64) -> bool {
    let (u, v) = (
        [o.b[0] - o.a[0], o.b[1] - o.a[1]],
        [b[0] - a[0], b[1] - a[1]],
    );
    let dot = u[0] * v[0] + u[1] * v[1];
    let norms = u[0].hypot(u[1]) * v[0].hypot(v[1]);
    dot < -0.5 * norms && o.distance(p) - o.half <= reach
}

/// Segments bucketed on a dense square grid over a fixed box, for nearby queries. Segments
/// outside the box are kept in a short list that every query scans (rare: the box covers the
/// layer and the one below).
///
/// Each cell's segments are a list threaded through one array (first and last entry per
/// cell, each entry its segment and the next entry), in the order they were entered: the
/// grid grows as strands are printed, and a vector per cell cost an allocation for every
/// cell a strand first entered (most of a plate's end checks) and as many frees after.
struct Grid {
    cell: f64,
    origin: [f64; 2],
    nx: i64,
    ny: i64,
    segs: Vec<Seg>,
    /// First and last entry of each cell, [`NONE`] when empty.
    head: Vec<u32>,
    tail: Vec<u32>,
    /// (segment, next entry of its cell or [`NONE`]).
    entries: Vec<(u32, u32)>,
    outside: Vec<u32>,
    max_half: f64,
    /// The widest half width entered in each cell: a query passes over a cell farther from
    /// it than its reach and that (a few absurdly wide beads of a damaged file raise
    /// `max_half` to 5 mm, and every query then read the strands of a hundred cells: a
    /// check of 30 s, 2.5 s with the far cells passed over).
    cell_half: Vec<f32>,
    /// Whether every query lies in the box ([`Grid::clamped`]).
    clamped: bool,
}

/// No entry.
const NONE: u32 = u32::MAX;

/// `v` rounded down, as an integer (`as` saturates; NaN gives 0). `f64::floor` is a call into
/// libm on the baseline target, made for every corner of every segment entered and asked.
fn floor_i64(v: f64) -> i64 {
    let n = v as i64;
    if (n as f64) > v {
        n.saturating_sub(1)
    } else {
        n
    }
}

/// Most cells a grid allocates; a layer spread wider gets coarser cells.
const MAX_CELLS: f64 = 250_000.0;

impl Grid {
    /// Distance (mm) from the grid beyond which no piece of a long segment is entered: more
    /// than a bead's reach (10 mm) and an anchor's (four beads) from any query.
    const FAR: f64 = 50.0;

    fn new(cell: f64, min: [f64; 2], max: [f64; 2]) -> Grid {
        // Beads are at most 10 mm wide (see `seg_width`): a margin of half that keeps every
        // padded segment of the box inside the grid.
        const MARGIN: f64 = 6.0;
        let min = [min[0] - MARGIN, min[1] - MARGIN];
        let max = [max[0] + MARGIN, max[1] + MARGIN];
        let (w, h) = ((max[0] - min[0]).max(0.0), (max[1] - min[1]).max(0.0));
        let cell = cell.max(((w + 2.0) * (h + 2.0) / MAX_CELLS).sqrt());
        let nx = ((w / cell).ceil() as i64 + 1).max(1);
        let ny = ((h / cell).ceil() as i64 + 1).max(1);
        Grid {
            cell,
            origin: min,
            nx,
            ny,
            segs: Vec::new(),
            head: vec![NONE; (nx * ny) as usize],
            tail: vec![NONE; (nx * ny) as usize],
            entries: Vec::new(),
            outside: Vec::new(),
            max_half: 0.0,
            cell_half: vec![0.0; (nx * ny) as usize],
            clamped: false,
        }
    }

    /// The grid for queries that all lie in its box (a check's samples): segments out of it
    /// are entered in its edge cells instead of the list every query scans.
    fn clamped(mut self) -> Grid {
        self.clamped = true;
        self
    }

    fn key(&self, x: f64, y: f64) -> (i64, i64) {
        (
            floor_i64((x - self.origin[0]) / self.cell),
            floor_i64((y - self.origin[1]) / self.cell),
        )
    }

    /// The segments entered in cell `c`, in the order they were entered.
    fn cell(&self, c: usize) -> impl Iterator<Item = u32> + '_ {
        let mut e = self.head[c];
        std::iter::from_fn(move || {
            let (seg, next) = *self.entries.get(e as usize)?;
            e = next;
            Some(seg)
        })
    }

    fn enter(&mut self, c: usize, seg: u32) {
        let e = self.entries.len() as u32;
        self.entries.push((seg, NONE));
        match self.tail[c] {
            NONE => self.head[c] = e,
            t => self.entries[t as usize].1 = e,
        }
        self.tail[c] = e;
    }

    fn insert(&mut self, s: Seg) {
        // A long segment goes in as pieces about one cell long, so that it lands only in the
        // cells along it rather than in every cell of its bounding box.
        let len = ((s.b[0] - s.a[0]).powi(2) + (s.b[1] - s.a[1]).powi(2)).sqrt();
        let n = (len / self.cell).ceil();
        if n > 1.0 && n < 1e6 {
            let n = n as usize;
            let at = |t: f64| {
                [
                    s.a[0] + t * (s.b[0] - s.a[0]),
                    s.a[1] + t * (s.b[1] - s.a[1]),
                ]
            };
            // Only the pieces near the grid: queries lie in it, and reach at most a bead's
            // width (10 mm) and an anchor's four out of it. A damaged file's metre-long move
            // across a small window put a million pieces in `outside`, which every query
            // scans (a minute for one region's check). The pieces kept are cut as they would
            // be from the whole segment.
            let far = Self::FAR;
            let reach = (
                [self.origin[0] - far, self.origin[1] - far],
                [
                    self.origin[0] + self.nx as f64 * self.cell + far,
                    self.origin[1] + self.ny as f64 * self.cell + far,
                ],
            );
            let Some((t0, t1)) = clip_to_box(s.a, s.b, reach) else {
                return;
            };
            let first = ((t0 * n as f64).floor() as usize).min(n - 1);
            let last = ((t1 * n as f64).ceil() as usize).clamp(first + 1, n);
            for k in first..last {
                self.insert_piece(Seg {
                    a: at(k as f64 / n as f64),
                    b: at((k + 1) as f64 / n as f64),
                    half: s.half,
                });
            }
        } else {
            self.insert_piece(s);
        }
    }

    fn insert_piece(&mut self, s: Seg) {
        let id = self.segs.len() as u32;
        // Entered in the cells its centreline crosses, not padded by its half width: queries
        // reach `max_half` farther anyway, and a padded bead of a width the file's E makes
        // absurd went into hundreds of cells (120 000 moves a layer with 3-11 mm beads: 313 MB
        // for `poa check`).
        let (x0, y0) = self.key(s.a[0].min(s.b[0]), s.a[1].min(s.b[1]));
        let (x1, y1) = self.key(s.a[0].max(s.b[0]), s.a[1].max(s.b[1]));
        self.max_half = self.max_half.max(s.half);
        let inside = x0 >= 0 && y0 >= 0 && x1 < self.nx && y1 < self.ny;
        let (x0, y0, x1, y1) = if !inside && self.clamped && x0 <= x1 && y0 <= y1 {
            // Queries lie in the grid: a piece out of it is entered in the cells of its box
            // moved into the grid, whose nearest point to any query is no farther than the
            // piece's (the projection onto a box brings no point farther from one inside
            // it). Pieces beyond any query's reach are not entered at all. (A long strand of
            // the layer below running just outside a narrow window put thousands of pieces in
            // `outside`, which every query scans.)
            let far = (Self::FAR / self.cell).ceil() as i64;
            if x1 < -far || y1 < -far || x0 >= self.nx + far || y0 >= self.ny + far {
                self.segs.push(s);
                return;
            }
            (
                x0.clamp(0, self.nx - 1),
                y0.clamp(0, self.ny - 1),
                x1.clamp(0, self.nx - 1),
                y1.clamp(0, self.ny - 1),
            )
        } else {
            (x0, y0, x1, y1)
        };
        if !(self.clamped || inside) || !(x0 <= x1 && y0 <= y1) {
            self.outside.push(id);
        } else {
            for y in y0..=y1 {
                for x in x0..=x1 {
                    let c = (y * self.nx + x) as usize;
                    self.enter(c, id);
                    self.cell_half[c] = self.cell_half[c].max(s.half as f32);
                }
            }
        }
        self.segs.push(s);
    }

    /// Whether material lies within `reach` of `p` (edge of a bead, not its centreline).
    /// `last` is the segment that answered the previous query: consecutive samples of a
    /// strand usually rest on the same one, so it is tried first.
    fn near(&self, p: [f64; 2], reach: f64, last: &mut Option<u32>) -> bool {
        let hit = |i: u32| {
            let s = &self.segs[i as usize];
            s.distance(p) - s.half <= reach
        };
        if last.is_some_and(hit) {
            return true;
        }
        let found = self.search(p, reach, &hit);
        *last = found;
        found.is_some()
    }

    fn search(&self, p: [f64; 2], reach: f64, hit: &impl Fn(u32) -> bool) -> Option<u32> {
        let r = reach + self.max_half;
        let (x0, y0) = self.key(p[0] - r, p[1] - r);
        let (x1, y1) = self.key(p[0] + r, p[1] + r);
        for y in y0.max(0)..=y1.min(self.ny - 1) {
            let (cy0, cy1) = (
                self.origin[1] + y as f64 * self.cell,
                self.origin[1] + (y + 1) as f64 * self.cell,
            );
            let dy = (cy0 - p[1]).max(p[1] - cy1).max(0.0);
            for x in x0.max(0)..=x1.min(self.nx - 1) {
                let c = (y * self.nx + x) as usize;
                // Passed over when beyond reach of its widest bead. No hit is lost: a
                // piece near enough has its point nearest `p` in a cell of its box, where
                // it was entered, and that cell is no farther from `p` than the point.
                let (cx0, cx1) = (
                    self.origin[0] + x as f64 * self.cell,
                    self.origin[0] + (x + 1) as f64 * self.cell,
                );
                let dx = (cx0 - p[0]).max(p[0] - cx1).max(0.0);
                // (A micrometre more than the half widths' rounding to f32: 0.3 um at 5 mm.)
                let r_cell = reach + f64::from(self.cell_half[c]) + 1e-6;
                if dx * dx + dy * dy > r_cell * r_cell {
                    continue;
                }
                let found = self.cell(c).find(|&i| hit(i));
                if found.is_some() {
                    return found;
                }
            }
        }
        self.outside.iter().copied().find(|&i| hit(i))
    }
}

/// The check's support model near one part of a layer, for the rewrite: which ends of a
/// slicer strand the check would find hanging in air (an unsupported run at a path's start or
/// end is never anchored on both sides). Holds the layer below and the strands of this layer
/// added so far, inside a box (segments outside it are left out: queries stay inside it).
pub struct EndSupport {
    grid: Grid,
    boxes: Vec<([f64; 2], [f64; 2])>,
    filament_area: f64,
    opts: CheckOptions,
}

/// Widest angle (rad) between a strand's direction out of its end and the anchor drawn on
/// from it: an anchor may turn aside to a neighbouring bead, not double back along the run
/// it is to hold (which would hold nothing).
const ANCHOR_CONE: f64 = 150.0 * std::f64::consts::PI / 180.0;

impl EndSupport {
    /// The model of the layers `below` (those the layer rests on) inside the boxes (lower,
    /// upper corner).
    pub fn new(below: &[&Layer], boxes: &[([f64; 2], [f64; 2])], filament_area: f64) -> EndSupport {
        let (lo, hi) = boxes.iter().fold(
            ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]),
            |(lo, hi), (l, h)| {
                (
                    [lo[0].min(l[0]), lo[1].min(l[1])],
                    [hi[0].max(h[0]), hi[1].max(h[1])],
                )
            },
        );
        let (lo, hi) = if lo[0] <= hi[0] {
            (lo, hi)
        } else {
            ([0.0; 2], [0.0; 2])
        };
        let mut sup = EndSupport {
            grid: Grid::new(1.0, lo, hi),
            boxes: boxes.to_vec(),
            filament_area,
            opts: CheckOptions::default(),
        };
        for s in below.iter().flat_map(|b| segments(b, filament_area, false)) {
            sup.insert(s);
        }
        sup
    }

    fn insert(&mut self, s: Seg) {
        // Beads are at most 10 mm wide: a segment farther than that from the box supports
        // nothing in it.
        let m = s.half + 0.5;
        let meets = self.boxes.iter().any(|(lo, hi)| {
            s.a[0].max(s.b[0]) + m >= lo[0]
                && s.a[0].min(s.b[0]) - m <= hi[0]
                && s.a[1].max(s.b[1]) + m >= lo[1]
                && s.a[1].min(s.b[1]) - m <= hi[1]
        });
        if meets {
            self.grid.insert(s);
        }
    }

    /// Adds a strand of this layer (printed before the strands judged next).
    pub fn add(&mut self, path: &Path) {
        for i in 0..path.points.len().saturating_sub(1) {
            let s = Seg {
                a: path.points[i],
                b: path.points[i + 1],
                half: seg_width(path, i, self.filament_area) / 2.0,
            };
            self.insert(s);
        }
    }

    /// The nearest point to `end` (at most `max` mm away) where a strand of width `w` would
    /// be supported, with a sample's half step to spare: where a strand hanging off at `end`
    /// can be extended to, so that its run over air is held at both ends.
    /// `ahead` is the strand's direction out of `end`: an anchor goes on or aside (within
    /// [`ANCHOR_CONE`] of it), never straight back over the run it is to hold.
    pub fn anchor(&self, end: [f64; 2], ahead: [f64; 2], w: f64, max: f64) -> Option<[f64; 2]> {
        let g = &self.grid;
        if !(end[0].is_finite() && end[1].is_finite()) || g.segs.is_empty() {
            return None;
        }
        let reach = (0.5 - self.opts.overlap_min) * w;
        let r = max + g.max_half + reach;
        let (x0, y0) = g.key(end[0] - r, end[1] - r);
        let (x1, y1) = g.key(end[0] + r, end[1] + r);
        let mut best: Option<(f64, [f64; 2])> = None;
        let candidates = (y0.max(0)..=y1.min(g.ny - 1))
            .flat_map(|y| (x0.max(0)..=x1.min(g.nx - 1)).map(move |x| (y * g.nx + x) as usize))
            .flat_map(|c| g.cell(c))
            .chain(g.outside.iter().copied());
        for i in candidates {
            let s = &g.segs[i as usize];
            let (_, c) = nearest_on_segment(end, s.a, s.b);
            let d = ((end[0] - c[0]).powi(2) + (end[1] - c[1]).powi(2)).sqrt();
            // Deep enough that the samples of the last step are held too.
            let need = (s.half + reach - self.opts.step).max(0.0);
            let go = (d - need).max(0.0);
            let dir = (c[0] - end[0]) * ahead[0] + (c[1] - end[1]) * ahead[1];
            let forward = d > 1e-9 && dir >= ANCHOR_CONE.cos() * d * ahead[0].hypot(ahead[1]);
            if go <= max && best.is_none_or(|b| go < b.0) && forward {
                let f = go / d;
                best = Some((
                    go,
                    [end[0] + (c[0] - end[0]) * f, end[1] + (c[1] - end[1]) * f],
                ));
            }
        }
        best.map(|b| b.1)
    }

    /// The unsupported runs at the start and at the end of `path` (cumulative length from
    /// its start to its first supported sample, and from its last supported sample to its
    /// end), sampled as [`check_layer`] samples it, a path's own segments supporting it from two
    /// widths behind as in the check. `None` when a run is longer than `max_run` mm (no
    /// supported sample within it).
    pub fn dangling(&self, path: &Path, max_run: f64) -> Option<(f64, f64)> {
        let opts = &self.opts;
        // Every segment with a length: where it starts along the path, its length and width.
        struct Piece {
            start: f64,
            len: f64,
            seg: Seg,
            w: f64,
        }
        let mut segs: Vec<Piece> = Vec::with_capacity(path.points.len());
        let mut along = 0.0;
        for i in 0..path.points.len().saturating_sub(1) {
            let (a, b) = (path.points[i], path.points[i + 1]);
            let len = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt();
            if len > 1e-9 {
                let w = seg_width(path, i, self.filament_area);
                let seg = Seg {
                    a,
                    b,
                    half: w / 2.0,
                };
                segs.push(Piece {
                    start: along,
                    len,
                    seg,
                    w,
                });
                along += len;
            }
        }
        let total = along;
        let mut hint = None;
        // Whether the sample `k` of `n` of segment `i` is held; its distance along the path.
        let mut sample = |i: usize, k: usize, n: usize| -> (f64, bool) {
            let Piece {
                start,
                len,
                seg: s,
                w,
            } = segs[i];
            let t = (k as f64 + 0.5) / n as f64;
            let p = [
                s.a[0] + t * (s.b[0] - s.a[0]),
                s.a[1] + t * (s.b[1] - s.a[1]),
            ];
            let at = start + t * len;
            let reach = (0.5 - opts.overlap_min) * w;
            let held = self.grid.near(p, reach, &mut hint)
                || segs[..i].iter().any(|o| {
                    (at - (o.start + o.len) >= 2.0 * w && o.seg.distance(p) - o.seg.half <= reach)
                        || turned_back(&o.seg, s.a, s.b, p, reach)
                });
            (at, held)
        };
        let count = |i: usize| ((segs[i].len / opts.step).ceil() as usize).clamp(1, 1_000_000);
        // The first held sample from the start, within `max_run`.
        let mut head = None;
        'head: for (i, piece) in segs.iter().enumerate() {
            if piece.start > max_run {
                break;
            }
            let n = count(i);
            for k in 0..n {
                let (at, held) = sample(i, k, n);
                if at > max_run {
                    break 'head;
                }
                if held {
                    head = Some(if i == 0 && k == 0 { 0.0 } else { at });
                    break 'head;
                }
            }
        }
        let mut tail = None;
        'tail: for i in (0..segs.len()).rev() {
            let n = count(i);
            for k in (0..n).rev() {
                let (at, held) = sample(i, k, n);
                if total - at > max_run {
                    break 'tail;
                }
                if held {
                    let last = i + 1 == segs.len() && k + 1 == n;
                    tail = Some(if last { 0.0 } else { total - at });
                    break 'tail;
                }
            }
        }
        Some((head?, tail?))
    }
}

/// Bounding box of the points of `layers`' paths.
fn bounds<'a>(layers: impl Iterator<Item = &'a Layer>) -> ([f64; 2], [f64; 2]) {
    let mut min = [f64::INFINITY; 2];
    let mut max = [f64::NEG_INFINITY; 2];
    for p in layers
        .flat_map(|l| l.paths.iter())
        .flat_map(|p| p.points.iter())
    {
        if p[0].is_finite() && p[1].is_finite() {
            min = [min[0].min(p[0]), min[1].min(p[1])];
            max = [max[0].max(p[0]), max[1].max(p[1])];
        }
    }
    if min[0] > max[0] {
        ([0.0; 2], [0.0; 2])
    } else {
        (min, max)
    }
}

/// The fate of one strand sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Support {
    Supported,
    Bridged,
    InAir,
}

/// One sample of a strand.
#[derive(Debug, Clone, Copy)]
pub struct Sample {
    pub point: [f64; 2],
    /// Source line of the segment holding the sample.
    pub line: u64,
    /// Length of path this sample stands for (mm).
    pub length: f64,
    pub support: Support,
}

/// Results for one layer.
#[derive(Debug, Clone, Default, Serialize)]
pub struct LayerCheck {
    pub layer: usize,
    pub z: f64,
    pub length_mm: f64,
    pub supported_mm: f64,
    pub bridged_mm: f64,
    pub in_air_mm: f64,
    pub longest_in_air_mm: f64,
    /// Where the longest in-air run starts: [x, y] and line.
    pub longest_in_air_at: Option<([f64; 2], u64)>,
    /// Extruded volume / footprint area / height.
    pub density: f64,
    /// Filament pushed on this layer's extrusions (mm).
    pub filament_mm: f64,
    #[serde(skip)]
    pub samples: Vec<Sample>,
}

/// Width of a segment's bead from its E.
fn seg_width(path: &Path, i: usize, filament_area: f64) -> f64 {
    let (a, b) = (path.points[i], path.points[i + 1]);
    let len = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt();
    flow_width(path.seg_e[i], len, path.height, filament_area).clamp(0.0, 10.0)
}

/// The layer's bead segments; only its support material's with `support_only`.
fn segments(
    layer: &Layer,
    filament_area: f64,
    support_only: bool,
) -> impl Iterator<Item = Seg> + '_ {
    segments_of(layer, filament_area, support_only, |_| true)
}

/// [`segments`] of the paths `keep` keeps.
fn segments_of<'a>(
    layer: &'a Layer,
    filament_area: f64,
    support_only: bool,
    keep: impl Fn(&Path) -> bool + 'a,
) -> impl Iterator<Item = Seg> + 'a {
    let paths = layer.paths.iter();
    paths
        .filter(move |p| (!support_only || p.role.is_support()) && keep(p))
        .flat_map(move |p| {
            (0..p.points.len().saturating_sub(1)).map(move |i| Seg {
                a: p.points[i],
                b: p.points[i + 1],
                // The first layer's beads squash out past their E-width (its spread).
                half: seg_width(p, i, filament_area) / 2.0 + layer.spread,
            })
        })
}

/// The layers among `recent` (earlier layers, in any order) that `layer` rests on
/// ([`Layer::rests_on`]), then those whose support material holds it across the contact gap
/// ([`Layer::contact`]; only their support strands count, see [`check_layer`]), then those
/// its own support material stands on across the bottom contact gap ([`Layer::gap_below`];
/// they hold its support strands only).
pub fn resting_on<'a>(
    layer: &Layer,
    recent: impl Iterator<Item = &'a Layer> + Clone,
) -> Vec<&'a Layer> {
    let mut seen: Vec<usize> = Vec::new();
    layer
        .rests_on
        .iter()
        .chain(&layer.contact)
        .chain(&layer.gap_below)
        .filter(|&&i| {
            let new = !seen.contains(&i);
            seen.push(i);
            new
        })
        .filter_map(|&i| {
            recent
                .clone()
                .find(|l| l.index == i && l.kind == layer.kind)
        })
        .collect()
}

/// Checks `layer` against the layers below it (those it rests on: one, unless objects of
/// different layer heights interleave). `keep_samples` keeps every sample (for pictures and
/// tests).
///
/// Long by design: measures one layer's strands against the layer below in one pass, with the per-layer tallies every case updates.
pub fn check_layer(
    below: &[&Layer],
    layer: &Layer,
    filament_area: f64,
    opts: &CheckOptions,
    keep_samples: bool,
) -> LayerCheck {
    check_within(
        below,
        &[],
        layer,
        filament_area,
        opts,
        Wants {
            samples: keep_samples,
            density: true,
            only_near: None,
        },
        None,
    )
}

/// [`check_layer`] with the layers under those below (`deeper`), which hold the layer's
/// sparse infill where it is printed taller than the layer: Cura's `infill_sparse_thickness`
/// lays it every other layer at twice the height (E for twice the width at the layer's
/// height), on the infill two layers down, and none on the layer between.
pub fn check_layer_over(
    below: &[&Layer],
    deeper: &[&Layer],
    layer: &Layer,
    filament_area: f64,
    opts: &CheckOptions,
) -> LayerCheck {
    check_within(
        below,
        deeper,
        layer,
        filament_area,
        opts,
        Wants {
            samples: false,
            density: true,
            only_near: None,
        },
        None,
    )
}

/// E-width above which a layer's sparse infill is taller than the layer ([`check_layer_over`]):
/// 1.7 times the median E-width of its walls, by length (a square's single wall is four
/// segments: counted by segment, too few to judge, and the infill of a one-wall part printed
/// every other layer read 2.7 m in air).
fn tall_infill_width(layer: &Layer, filament_area: f64) -> Option<f64> {
    if !layer.paths.iter().any(|p| p.role == Role::Infill) {
        return None;
    }
    let mut widths: Vec<(f64, f64)> = layer
        .paths
        .iter()
        .filter(|p| matches!(p.role, Role::ExternalPerimeter | Role::Perimeter))
        .flat_map(|p| (0..p.points.len().saturating_sub(1)).map(move |i| (p, i)))
        .map(|(p, i)| {
            let (a, b) = (p.points[i], p.points[i + 1]);
            let len = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt();
            (seg_width(p, i, filament_area), len)
        })
        .filter(|(w, len)| *w > 0.0 && *len > 0.0)
        .collect();
    let total: f64 = widths.iter().map(|w| w.1).sum();
    if total < MIN_WALL_JUDGED {
        return None;
    }
    widths.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut seen = 0.0;
    let median = widths.iter().find(|(_, len)| {
        seen += len;
        seen >= total / 2.0
    })?;
    Some(TALL_INFILL * median.0)
}

/// Wall length (mm) a layer needs for its walls' width to be judged.
const MIN_WALL_JUDGED: f64 = 5.0;

/// See [`tall_infill_width`].
const TALL_INFILL: f64 = 1.7;

/// [`check_layer`] with its samples and no density (0): what the rewrite reads of a layer
/// with bridges to judge.
pub fn check_layer_samples(below: &[&Layer], layer: &Layer, filament_area: f64) -> LayerCheck {
    for_rewrite(below, layer, filament_area, None, true)
}

/// [`check_layer`] of the strands of `layer` that come within `window`, with their samples
/// (no density: 0).
pub fn check_layer_within(
    below: &[&Layer],
    layer: &Layer,
    filament_area: f64,
    window: ([f64; 2], [f64; 2]),
) -> LayerCheck {
    for_rewrite(below, layer, filament_area, Some(window), true)
}

/// In-air length (mm) of the strands of `layer` that come within `window` (min, max
/// corners), judged as [`check_layer`] judges them: only what lies near the window is
/// looked at (a rewritten region's neighbourhood on a plate-wide layer).
pub fn in_air_within(
    below: &[&Layer],
    layer: &Layer,
    filament_area: f64,
    window: ([f64; 2], [f64; 2]),
) -> f64 {
    for_rewrite(below, layer, filament_area, Some(window), false).in_air_mm
}

/// Samples (with their lengths) of `layer`'s strands inside the boxes `windows` (min, max
/// corners), judged as [`check_layer`] judges them but for the runs that leave the boxes:
/// there every sample outside counts as held, so that a run out of a box ends there,
/// anchored (a bridge's strands zigzag across a whole cap, and a check of their anchors
/// beside it need not sample the rest). Cheaper than [`check_layer_within`]; in-air lengths
/// inside the boxes can only be lower than it finds (a run shortened at a box's edge).
pub fn samples_inside(
    below: &[&Layer],
    layer: &Layer,
    filament_area: f64,
    windows: &[([f64; 2], [f64; 2])],
) -> Vec<Sample> {
    let Some(window) = windows.iter().copied().reduce(|a, b| {
        (
            [a.0[0].min(b.0[0]), a.0[1].min(b.0[1])],
            [a.1[0].max(b.1[0]), a.1[1].max(b.1[1])],
        )
    }) else {
        return Vec::new();
    };
    let wants = Wants {
        samples: true,
        density: false,
        only_near: Some(windows),
    };
    checked_as_rewrite(below, layer, filament_area, Some(window), wants)
        .samples
        .into_iter()
        .filter(|s| windows.iter().any(|w| inside_box(s.point, *w)))
        .collect()
}

/// The stretch (from t, to t) of the segment `a`-`b` inside the box `w` (min, max corners),
/// if it meets the box (Liang-Barsky).
fn clip_to_box(a: [f64; 2], b: [f64; 2], w: ([f64; 2], [f64; 2])) -> Option<(f64, f64)> {
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for k in 0..2 {
        let d = b[k] - a[k];
        if d.abs() < 1e-12 {
            if a[k] < w.0[k] || a[k] > w.1[k] {
                return None;
            }
            continue;
        }
        let (u, v) = ((w.0[k] - a[k]) / d, (w.1[k] - a[k]) / d);
        t0 = t0.max(u.min(v));
        t1 = t1.min(u.max(v));
    }
    (t0 <= t1).then_some((t0, t1))
}

/// Whether `p` lies in the box `w` (min, max corners).
pub(crate) fn inside_box(p: [f64; 2], w: ([f64; 2], [f64; 2])) -> bool {
    p[0] >= w.0[0] && p[0] <= w.1[0] && p[1] >= w.0[1] && p[1] <= w.1[1]
}

/// The checks the rewrite makes: default options, no density (it reads none).
fn for_rewrite(
    below: &[&Layer],
    layer: &Layer,
    filament_area: f64,
    window: Option<([f64; 2], [f64; 2])>,
    samples: bool,
) -> LayerCheck {
    let wants = Wants {
        samples,
        density: false,
        only_near: None,
    };
    checked_as_rewrite(below, layer, filament_area, window, wants)
}

/// [`check_within`] with the default options and no layers deeper.
fn checked_as_rewrite(
    below: &[&Layer],
    layer: &Layer,
    filament_area: f64,
    window: Option<([f64; 2], [f64; 2])>,
    wants: Wants<'_>,
) -> LayerCheck {
    let opts = CheckOptions::default();
    check_within(below, &[], layer, filament_area, &opts, wants, window)
}

/// Whether the box `a` meets the box `b` grown by `m`.
fn boxes_meet(a: ([f64; 2], [f64; 2]), b: ([f64; 2], [f64; 2]), m: f64) -> bool {
    a.0[0] <= b.1[0] + m && a.1[0] >= b.0[0] - m && a.0[1] <= b.1[1] + m && a.1[1] >= b.0[1] - m
}

/// The box of `points`.
fn points_bounds(points: &[[f64; 2]]) -> ([f64; 2], [f64; 2]) {
    points.iter().fold(
        ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]),
        |(lo, hi), p| {
            (
                [lo[0].min(p[0]), lo[1].min(p[1])],
                [hi[0].max(p[0]), hi[1].max(p[1])],
            )
        },
    )
}

/// Margin (mm) round a check's window within which the layer below still holds a strand
/// of it: more than any bead's half width.
const WINDOW_MARGIN: f64 = 6.0;

/// What a check keeps besides the lengths: the samples, the layer's density.
#[derive(Debug, Clone, Copy)]
struct Wants<'w> {
    samples: bool,
    density: bool,
    /// Samples outside these boxes count as held, unsampled ([`samples_inside`]).
    only_near: Option<&'w [([f64; 2], [f64; 2])]>,
}

fn check_within(
    below: &[&Layer],
    deeper: &[&Layer],
    layer: &Layer,
    filament_area: f64,
    opts: &CheckOptions,
    wants: Wants,
    window: Option<([f64; 2], [f64; 2])>,
) -> LayerCheck {
    let Wants {
        samples: keep_samples,
        density,
        only_near,
    } = wants;
    // A strand of the layer this far out holds no sample of the window.
    let far = |s: &Seg| {
        only_near.is_some_and(|ws| {
            let b = points_bounds(&[s.a, s.b]);
            !ws.iter().any(|w| boxes_meet(b, *w, WINDOW_MARGIN))
        })
    };
    let outside = |p: [f64; 2]| only_near.is_some_and(|ws| !ws.iter().any(|w| inside_box(p, *w)));
    // Below, the strands near the boxes only (a plate's layer has thousands).
    let below_near = |p: &Path| {
        only_near.is_none_or(|ws| {
            let b = points_bounds(&p.points);
            ws.iter().any(|w| boxes_meet(b, *w, WINDOW_MARGIN))
        })
    };
    let mut result = LayerCheck {
        layer: layer.index + 1,
        z: layer.z,
        ..Default::default()
    };
    // Paths that come within the window are judged whole (their runs need their ends).
    let judged = |p: &Path| window.is_none_or(|w| boxes_meet(points_bounds(&p.points), w, 0.0));
    let (min, max) = match window {
        Some(_) => {
            let near: Vec<[f64; 2]> = layer
                .paths
                .iter()
                .filter(|p| judged(p))
                .flat_map(|p| p.points.iter().copied())
                .collect();
            let (lo, hi) = points_bounds(&near);
            if lo[0] > hi[0] {
                return result;
            }
            (
                [lo[0] - WINDOW_MARGIN, lo[1] - WINDOW_MARGIN],
                [hi[0] + WINDOW_MARGIN, hi[1] + WINDOW_MARGIN],
            )
        }
        None => bounds(below.iter().copied().chain(std::iter::once(layer))),
    };
    let mut grid = Grid::new(1.0, min, max).clamped();
    // What the layer's support material stands on across its bottom contact gap.
    let mut gap = Grid::new(1.0, min, max).clamped();
    let mut gapped = false;
    let on_bed = layer.on_bed();
    let in_window =
        |s: &Seg| window.is_none() || boxes_meet(points_bounds(&[s.a, s.b]), (min, max), 0.0);
    for b in below {
        let rests = layer.rests_on.contains(&b.index);
        let contact = layer.contact.contains(&b.index);
        if !rests && layer.gap_below.contains(&b.index) {
            for s in segments_of(b, filament_area, false, below_near).filter(in_window) {
                gap.insert(s);
                gapped = true;
            }
            if !contact {
                continue;
            }
        }
        // A layer under the contact gap holds this one by its support material only.
        let support_only = contact && !rests;
        for s in segments_of(b, filament_area, support_only, below_near).filter(in_window) {
            grid.insert(s);
        }
    }
    let tall_at = (!deeper.is_empty())
        .then(|| tall_infill_width(layer, filament_area))
        .flatten();
    let mut deep = Grid::new(1.0, min, max).clamped();
    if tall_at.is_some() {
        for s in deeper
            .iter()
            .flat_map(|b| segments(b, filament_area, false))
        {
            deep.insert(s);
        }
    }
    let mut volume = 0.0;
    for path in layer.paths.iter().filter(|p| judged(p)) {
        let infill = path.role == Role::Infill;
        let support = gapped && path.role.is_support();
        let mut last_gap = None;
        // A path is sampled every `step` up to [`MAX_PATH_SAMPLES`] samples, more coarsely
        // beyond: its samples are held until its runs are classified, and a path kilometres
        // long (moves gone relative by a stray G91) took gigabytes.
        let length: f64 = path
            .points
            .windows(2)
            .map(|w| (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]))
            .sum();
        let step = opts.step.max(length / MAX_PATH_SAMPLES);
        let mut last_deep = None;
        // (distance along the path, sample, supported?)
        let mut samples: Vec<(f64, Sample, bool)> = Vec::new();
        // The path's own segments wait until they are two widths behind.
        let mut own: std::collections::VecDeque<(f64, Seg)> = Default::default();
        let mut along = 0.0;
        let mut last = None;
        for i in 0..path.points.len().saturating_sub(1) {
            let (a, b) = (path.points[i], path.points[i + 1]);
            let len = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt();
            let w = seg_width(path, i, filament_area);
            volume += path.seg_e[i] * filament_area;
            result.filament_mm += path.seg_e[i];
            if len <= 1e-9 {
                continue;
            }
            let reach = (0.5 - opts.overlap_min) * w;
            // Pieces of the segment (from t, to t, samples, held without looking): all of
            // it; or, sampled only near boxes, its stretch within them, and one held sample
            // for each stretch out of them.
            let pieces: Vec<(f64, f64, usize, bool)> = match only_near {
                None => vec![(0.0, 1.0, ((len / step).ceil() as usize).max(1), false)],
                Some(ws) => match ws
                    .iter()
                    .filter_map(|w| clip_to_box(a, b, *w))
                    .reduce(|x, y| (x.0.min(y.0), x.1.max(y.1)))
                {
                    None => vec![(0.0, 1.0, 1, true)],
                    Some((t0, t1)) => {
                        let mut v = Vec::with_capacity(3);
                        if t0 > 0.0 {
                            v.push((0.0, t0, 1, true));
                        }
                        v.push((
                            t0,
                            t1,
                            (((t1 - t0) * len / step).ceil() as usize).max(1),
                            false,
                        ));
                        if t1 < 1.0 {
                            v.push((t1, 1.0, 1, true));
                        }
                        v
                    }
                },
            };
            for (t0, t1, n, held) in pieces {
                for k in 0..n {
                    // A held stretch's sample sits at the box's edge, where the run it
                    // anchors leaves the box.
                    // (Half a sample step out of the box: it is not one of the box's.)
                    let out = (0.5 * step / len).min(0.5 * (t1 - t0));
                    let t = match (held, t0 == 0.0, t1 == 1.0) {
                        (true, true, false) => t1 - out,
                        (true, false, true) => t0 + out,
                        _ => t0 + (t1 - t0) * (k as f64 + 0.5) / n as f64,
                    };
                    let p = [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])];
                    let s_here = along + t * len;
                    while let Some((end, _)) = own.front() {
                        if s_here - end >= 2.0 * w {
                            if let Some((_, seg)) = own.pop_front() {
                                if !far(&seg) {
                                    grid.insert(seg);
                                }
                            }
                        } else {
                            break;
                        }
                    }
                    let ok = on_bed
                        || held
                        || outside(p)
                        || grid.near(p, reach, &mut last)
                        || own.iter().any(|(_, o)| turned_back(o, a, b, p, reach))
                        || (infill
                            && tall_at.is_some_and(|t| w > t)
                            && deep.near(p, reach, &mut last_deep))
                        || (support && gap.near(p, reach, &mut last_gap));
                    samples.push((
                        s_here,
                        Sample {
                            point: p,
                            line: path.seg_line[i],
                            length: len * (t1 - t0) / n as f64,
                            support: Support::Supported,
                        },
                        ok,
                    ));
                }
            }
            along += len;
            own.push_back((
                along,
                Seg {
                    a,
                    b,
                    half: w / 2.0,
                },
            ));
        }
        for (_, seg) in own {
            if !far(&seg) {
                grid.insert(seg);
            }
        }
        classify(&mut samples, opts, &mut result);
        if keep_samples {
            result.samples.extend(samples.into_iter().map(|s| s.1));
        }
    }
    // The density's footprint buffers every vertex of the layer: past [`MAX_DENSITY_POINTS`]
    // (a layer of a million tiny moves took 330 MB and 5 s) it is not reported (0); nor where
    // it is not asked for (the rewrite's judge, which reads in-air lengths and samples only:
    // the whole layer's footprint, twice a rewritten layer, was a quarter of a plate of
    // bowls' rewrite).
    let points: usize = layer.paths.iter().map(|p| p.points.len()).sum();
    let area = if points > MAX_DENSITY_POINTS || !density {
        0.0
    } else {
        // Not where the strands pile on each other (a damaged file): no density then.
        footprint_if_spread(
            layer
                .paths
                .iter()
                .map(|p| {
                    // The footprint of what E makes, not of what a comment says; widths rounded
                    // to 5 um so that strands share one buffer call per width (a 1 % error
                    // bound on density at 0.45 mm, far below what it is read for).
                    // Clamped as the beads' widths are ([`seg_width`]): a path whose E
                    // makes it metres wide (a damaged file) had the buffer run for minutes.
                    let mut q = p.clone();
                    q.width = (p.e_width(filament_area).clamp(0.0, 10.0) * 200.0).round() / 200.0;
                    q
                })
                .collect::<Vec<_>>()
                .iter(),
        )
        .map_or(0.0, |a| a.unsigned_area())
    };
    if area > 0.0 && layer.height > 0.0 {
        result.density = volume / area / layer.height;
    }
    result
}

/// Most vertices of a layer whose density is measured.
const MAX_DENSITY_POINTS: usize = 500_000;

/// Most samples held for one path (~110 MB): 200 m of path at the 0.1 mm step, a whole
/// 300 x 300 mm solid layer printed as one path.
const MAX_PATH_SAMPLES: f64 = 2_000_000.0;

/// Turns per-sample supported flags into supported / bridged / in-air runs.
fn classify(samples: &mut [(f64, Sample, bool)], opts: &CheckOptions, out: &mut LayerCheck) {
    let n = samples.len();
    let mut i = 0;
    while i < n {
        if samples[i].2 {
            out.supported_mm += samples[i].1.length;
            out.length_mm += samples[i].1.length;
            i += 1;
            continue;
        }
        let start = i;
        while i < n && !samples[i].2 {
            i += 1;
        }
        let span_from = if start > 0 {
            samples[start - 1].0
        } else {
            samples[start].0
        };
        let span_to = if i < n {
            samples[i].0
        } else {
            samples[i - 1].0
        };
        let anchored = start > 0 && i < n;
        let bridged = anchored && span_to - span_from <= opts.max_bridge;
        let run: f64 = samples[start..i].iter().map(|s| s.1.length).sum();
        out.length_mm += run;
        for s in &mut samples[start..i] {
            s.1.support = if bridged {
                Support::Bridged
            } else {
                Support::InAir
            };
        }
        if bridged {
            out.bridged_mm += run;
        } else {
            out.in_air_mm += run;
            if run > out.longest_in_air_mm {
                out.longest_in_air_mm = run;
                out.longest_in_air_at = Some((samples[start].1.point, samples[start].1.line));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_grid_answers_as_a_scan_of_every_segment_with_a_few_beads_absurdly_wide() {
        // Beads of 0.2-0.6 mm and, here and there, one 10 mm wide (a damaged file's E): the
        // cells passed over (beyond reach of their widest bead) never hold the answer.
        let mut next = crate::geometry::testutil::lcg(12345);
        let mut grid = Grid::new(1.0, [0.0, 0.0], [40.0, 40.0]);
        let mut all = Vec::new();
        for k in 0..400 {
            let a = [next() * 40.0, next() * 40.0];
            let b = [a[0] + (next() - 0.5) * 6.0, a[1] + (next() - 0.5) * 6.0];
            let half = if k % 97 == 0 { 5.0 } else { 0.1 + 0.2 * next() };
            let s = Seg { a, b, half };
            all.push(s);
            grid.insert(s);
        }
        assert_answers_as_a_scan(&grid, &all, || {
            ([next() * 40.0, next() * 40.0], 0.05 + 0.3 * next())
        });
    }

    /// Asks `grid` 20 000 queries (a point and a reach) and compares each answer with a scan
    /// of all the segments entered; both answers come up often.
    fn assert_answers_as_a_scan(
        grid: &Grid,
        all: &[Seg],
        mut query: impl FnMut() -> ([f64; 2], f64),
    ) {
        let mut last = None;
        let (mut yes, mut no) = (0, 0);
        for _ in 0..20_000 {
            let (p, reach) = query();
            let scan = all.iter().any(|s| s.distance(p) - s.half <= reach);
            assert_eq!(grid.near(p, reach, &mut last), scan, "{p:?} reach {reach}");
            if scan {
                yes += 1;
            } else {
                no += 1;
            }
        }
        assert!(yes > 1000 && no > 1000, "{yes} near, {no} not");
    }

    #[test]
    fn a_clamped_grid_answers_as_a_scan_with_strands_just_outside_it() {
        // A window 2 mm high over long strands of the layer below running beside it, above
        // and below, crossing it and far away: out of the box they go to its edge cells (not
        // to the list every query scans), and every query in the box gets the answer a scan
        // of all segments gives.
        let mut next = crate::geometry::testutil::lcg(777);
        let (lo, hi) = ([0.0, 10.0], [30.0, 12.0]);
        let mut grid = Grid::new(1.0, lo, hi).clamped();
        let mut all = Vec::new();
        for k in 0..300 {
            let x = next() * 30.0;
            let side = if next() < 0.5 { -1.0 } else { 1.0 };
            let (a, b, half) = match k % 10 {
                // Long, just outside the grid's box (the window and a margin of 6 mm),
                // above or below it.
                0..=3 => {
                    let y = 11.0 + side * (7.02 + 0.6 * next());
                    ([x - 500.0, y], [x + 500.0, y + 0.3 * (next() - 0.5)], 0.2)
                }
                // Wide and far.
                4 => {
                    let y = 11.0 + side * (6.0 + 20.0 * next());
                    ([x, y], [x + 3.0, y + 1.0], 4.0)
                }
                // Short, anywhere near.
                _ => {
                    let y = 11.0 + (next() - 0.5) * 16.0;
                    (
                        [x, y],
                        [x + (next() - 0.5) * 3.0, y + (next() - 0.5) * 3.0],
                        0.2,
                    )
                }
            };
            let s = Seg { a, b, half };
            all.push(s);
            grid.insert(s);
        }
        assert!(grid.outside.is_empty(), "{} outside", grid.outside.len());
        // Anywhere in the grid's box.
        let (x0, y0) = (grid.origin[0], grid.origin[1]);
        let (w, h) = (grid.nx as f64 * grid.cell, grid.ny as f64 * grid.cell);
        assert_answers_as_a_scan(&grid, &all, || {
            ([x0 + next() * w, y0 + next() * h], 0.05 + 0.3 * next())
        });
    }

    #[test]
    fn a_segment_far_longer_than_the_grid_enters_only_its_pieces_near_it() {
        // A 10 mm grid and a 200 m move across it (a damaged file's): the pieces beyond
        // reach of any query are not entered (they went to `outside`, scanned by every
        // query), and what the grid answers near it is the same.
        let mut grid = Grid::new(1.0, [0.0, 0.0], [10.0, 10.0]);
        grid.insert(Seg {
            a: [-1e5, 5.0],
            b: [1e5, 5.0],
            half: 0.2,
        });
        let span = 10.0 + 2.0 * 6.0 + 2.0 * Grid::FAR;
        assert!(
            (grid.segs.len() as f64) <= span / grid.cell + 2.0,
            "{} pieces",
            grid.segs.len()
        );
        assert!(grid.outside.len() <= 2 * (Grid::FAR / grid.cell) as usize + 2);
        let mut last = None;
        for x in [-5.0, 0.0, 5.0, 9.9, 15.0] {
            assert!(grid.near([x, 5.3], 0.15, &mut last), "x {x}");
            assert!(!grid.near([x, 6.0], 0.1, &mut last), "x {x}");
        }
        // A segment wholly beyond reach enters nothing.
        grid.insert(Seg {
            a: [-1e5, 500.0],
            b: [1e5, 500.0],
            half: 0.2,
        });
        assert!((grid.segs.len() as f64) <= span / grid.cell + 2.0);
    }

    #[test]
    fn floor_of_an_integer_cast_is_the_floor() {
        for v in [
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            2.999,
            -2.001,
            1e15 + 0.5,
            -1e15 - 0.5,
        ] {
            assert_eq!(floor_i64(v), v.floor() as i64, "{v}");
        }
        assert_eq!(floor_i64(f64::NAN), 0);
        assert_eq!(floor_i64(f64::INFINITY), i64::MAX);
        assert_eq!(floor_i64(f64::NEG_INFINITY), i64::MIN);
    }
    use crate::layers::{filament_area, Role};

    /// A strand with the E of a `width` bead at 0.2 mm height on 1.75 mm filament.
    fn strand(points: Vec<[f64; 2]>, width: f64) -> Path {
        let h = 0.2;
        let area = (width - h) * h + std::f64::consts::PI * h * h / 4.0;
        let fa = filament_area(1.75);
        let seg_e = points
            .windows(2)
            .map(|w| ((w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1])) * area / fa)
            .collect();
        Path {
            role: Role::Unknown,
            width,
            height: h,
            z: 0.4,
            object: None,
            tool: 0,
            seg_line: vec![1; points.len() - 1],
            seg_e,
            points,
            feed: 1200.0,
        }
    }

    use crate::layers::testing::layer;

    fn circle(r: f64) -> Vec<[f64; 2]> {
        (0..=360)
            .map(|i| {
                let a = (i as f64).to_radians();
                [r * a.cos(), r * a.sin()]
            })
            .collect()
    }

    fn disk(r: f64) -> Layer {
        // Concentric rings 0.45 apart filling a disk.
        let mut paths = Vec::new();
        let mut rr = 0.45;
        while rr <= r {
            paths.push(strand(circle(rr), 0.45));
            rr += 0.45;
        }
        layer(1, paths)
    }

    fn rings(from: f64, to: f64, spacing: f64) -> Layer {
        let mut paths = Vec::new();
        let mut r = from;
        while r <= to {
            paths.push(strand(circle(r), 0.45));
            r += spacing;
        }
        layer(2, paths)
    }

    /// The layer below: two lines along X at Y 0 and Y 3 from X 0 to 10, and a wall along Y
    /// at X 12.
    fn ladder() -> Layer {
        layer(
            1,
            vec![
                strand(vec![[0.0, 0.0], [10.0, 0.0]], 0.45),
                strand(vec![[0.0, 3.0], [10.0, 3.0]], 0.45),
                strand(vec![[12.0, -5.0], [12.0, 5.0]], 0.45),
            ],
        )
    }

    #[test]
    fn a_strand_end_past_the_layer_below_dangles_and_is_anchored_on_the_wall() {
        let fa = filament_area(1.75);
        let below = ladder();
        let sup = EndSupport::new(&[&below], &[([-5.0, -5.0], [15.0, 5.0])], fa);
        // Along the line at Y 0, then 1.5 mm past its end, toward the wall at X 12.
        let s = strand(vec![[2.0, 0.0], [11.5 - 0.2, 0.0]], 0.45);
        let (head, tail) = sup.dangling(&s, 5.0).unwrap();
        assert_eq!(head, 0.0);
        // The line below ends at X 10 (its bead at 10 + a bit): about 1.1-1.3 mm hang.
        assert!(tail > 1.0 && tail < 1.4, "{tail}");
        // The run is what the check calls in air.
        let c = check_layer(
            &[&below],
            &layer(2, vec![s.clone()]),
            fa,
            &CheckOptions::default(),
            false,
        );
        assert!(
            (c.in_air_mm - tail).abs() < 0.11,
            "{} vs {tail}",
            c.in_air_mm
        );
        // The wall at X 12 is 0.7 mm from the end: an anchor reaches it; with the anchor the
        // run is held at both ends.
        let q = sup.anchor([11.3, 0.0], [1.0, 0.0], 0.45, 1.8).unwrap();
        assert!(q[0] > 11.3 && q[0] < 12.0 && q[1].abs() < 1e-9, "{q:?}");
        let mut long = s.clone();
        long.points.push(q);
        long.seg_e.push(s.seg_e[0] / 9.3 * (q[0] - 11.3));
        long.seg_line.push(2);
        let c = check_layer(
            &[&below],
            &layer(2, vec![long.clone()]),
            fa,
            &CheckOptions::default(),
            false,
        );
        assert!(c.in_air_mm < 1e-9 && c.bridged_mm > 1.0, "{c:?}");
        assert_eq!(sup.dangling(&long, 5.0).map(|d| d.1), Some(0.0));
        // Nothing within reach: no anchor; a run longer than asked for: not an end.
        assert!(sup.anchor([11.3, 0.0], [1.0, 0.0], 0.45, 0.3).is_none());
        assert!(sup.dangling(&s, 0.5).is_none());
        // A strand starting over air has a head run instead.
        let back = strand(vec![[11.3, 3.0], [2.0, 3.0]], 0.45);
        let (head, tail) = sup.dangling(&back, 5.0).unwrap();
        assert!(head > 1.0 && head < 1.4 && tail == 0.0, "{head} {tail}");
    }

    #[test]
    fn strokes_laid_back_and_forth_as_one_path_rest_on_each_other() {
        // Strokes across a gap 1.3 mm long, 0.27 mm apart, from a line below at Y 0; joined
        // by extruded connectors into one path, as they rest on each other joined by travels.
        let fa = filament_area(1.75);
        let below = layer(1, vec![strand(vec![[0.0, 0.0], [10.0, 0.0]], 0.45)]);
        let mut zigzag = vec![[0.0, 0.0], [1.3, 0.0]];
        let mut strokes = vec![strand(vec![[0.0, 0.0], [1.3, 0.0]], 0.45)];
        for k in 1..12 {
            let y = 0.27 * k as f64;
            let (a, b) = if k % 2 == 1 { (1.3, 0.0) } else { (0.0, 1.3) };
            zigzag.push([a, y]);
            zigzag.push([b, y]);
            strokes.push(strand(vec![[a, y], [b, y]], 0.45));
        }
        let opts = CheckOptions::default();
        let joined = check_layer(
            &[&below],
            &layer(2, vec![strand(zigzag, 0.45)]),
            fa,
            &opts,
            true,
        );
        let apart = check_layer(&[&below], &layer(2, strokes), fa, &opts, false);
        assert!(
            apart.in_air_mm < 1e-9 && apart.bridged_mm < 1e-9,
            "{apart:?}"
        );
        // Every stroke is held; what is not is the connectors (laid round a corner off the
        // fresh end of a stroke: short bridges), never in air.
        assert!(joined.in_air_mm < 1e-9, "{joined:?}");
        assert!(joined.bridged_mm <= 11.0 * 0.27 + 1e-9, "{joined:?}");
        for s in joined
            .samples
            .iter()
            .filter(|s| s.support != Support::Supported)
        {
            let y = s.point[1] / 0.27;
            assert!(
                (y - y.round()).abs() > 1e-6,
                "a stroke's sample at {:?} unsupported",
                s.point
            );
        }
        // A straight strand still does not hold itself: one running on past the line below
        // hangs.
        let on = check_layer(
            &[&below],
            &layer(2, vec![strand(vec![[5.0, 0.0], [5.0, 3.0]], 0.45)]),
            fa,
            &opts,
            false,
        );
        assert!(on.in_air_mm > 2.0, "{on:?}");
    }

    #[test]
    fn a_window_judges_the_strands_that_come_near_it_as_the_whole_check_does() {
        let fa = filament_area(1.75);
        let below = disk(5.0);
        let above = rings(4.9, 8.0, 0.45);
        let whole = check_layer(&[&below], &above, fa, &CheckOptions::default(), false);
        assert!(whole.in_air_mm > 10.0, "{whole:?}");
        // A strand is judged whole when its box meets the window: every ring's box holds
        // the centre.
        let all = in_air_within(&[&below], &above, fa, ([-1.0, -1.0], [1.0, 1.0]));
        assert!((all - whole.in_air_mm).abs() < 1e-6, "{all}");
        let over = in_air_within(&[&below], &above, fa, ([-9.0, -9.0], [9.0, 9.0]));
        assert!(
            (over - whole.in_air_mm).abs() < 1e-6,
            "{over} vs {}",
            whole.in_air_mm
        );
        // A window on one side still judges the rings crossing it in full.
        let side = in_air_within(&[&below], &above, fa, ([7.0, -0.5], [9.0, 0.5]));
        assert!(side > 0.0 && side <= whole.in_air_mm + 1e-6, "{side}");
        // Far away: nothing.
        assert_eq!(
            in_air_within(&[&below], &above, fa, ([50.0, 50.0], [60.0, 60.0])),
            0.0
        );
        // The same lengths and samples, without the whole layer's density (its footprint
        // is the costly part, and the rewrite's judge reads none of it).
        let windowed = check_layer_within(&[&below], &above, fa, ([-9.0, -9.0], [9.0, 9.0]));
        assert!(whole.density > 0.0 && windowed.density == 0.0);
        assert!((windowed.bridged_mm - whole.bridged_mm).abs() < 1e-6);
        assert!(!windowed.samples.is_empty());
    }

    #[test]
    fn samples_inside_boxes_are_those_the_whole_check_finds_there() {
        let fa = filament_area(1.75);
        let below = disk(5.0);
        let above = rings(4.9, 8.0, 0.45);
        let whole = check_layer(&[&below], &above, fa, &CheckOptions::default(), true);
        let boxes = [([6.0, -1.0], [9.0, 1.0]), ([-9.0, -1.0], [-6.0, 1.0])];
        let inside = |p: [f64; 2]| boxes.iter().any(|w| inside_box(p, *w));
        let near = samples_inside(&[&below], &above, fa, &boxes);
        // Only samples inside the boxes, at the whole check's spacing; held where the whole
        // check holds them, and no more in air (the rings' runs are cut at the boxes'
        // edges, where they count as anchored: in air there may read as bridged).
        assert!(near.iter().all(|s| inside(s.point)));
        let sum = |ss: &[&Sample], f: &dyn Fn(&Sample) -> bool| -> f64 {
            ss.iter().filter(|s| f(s)).map(|s| s.length).sum()
        };
        let there: Vec<&Sample> = whole.samples.iter().filter(|s| inside(s.point)).collect();
        let near: Vec<&Sample> = near.iter().collect();
        let held = |s: &Sample| s.support == Support::Supported;
        let in_air = |s: &Sample| s.support == Support::InAir;
        let all = |_: &Sample| true;
        assert!(sum(&there, &in_air) > 1.0);
        assert!(sum(&near, &in_air) <= sum(&there, &in_air) + 1e-6);
        let bridged = |s: &Sample| s.support != Support::Supported;
        assert!((sum(&near, &bridged) - sum(&there, &bridged)).abs() < 0.05 * sum(&there, &all));
        assert!((sum(&near, &held) - sum(&there, &held)).abs() < 0.05 * sum(&there, &all));
        assert!((sum(&near, &all) - sum(&there, &all)).abs() < 0.05 * sum(&there, &all));
        // No box: nothing.
        assert!(samples_inside(&[&below], &above, fa, &[]).is_empty());
    }

    #[test]
    fn a_segment_is_cut_to_the_part_of_it_in_a_box() {
        let w = ([0.0, 0.0], [1.0, 1.0]);
        assert_eq!(clip_to_box([-1.0, 0.5], [3.0, 0.5], w), Some((0.25, 0.5)));
        assert_eq!(clip_to_box([0.5, 0.5], [0.6, 0.6], w), Some((0.0, 1.0)));
        assert_eq!(clip_to_box([2.0, 0.5], [3.0, 0.5], w), None);
        assert_eq!(clip_to_box([-1.0, 2.0], [2.0, 2.0], w), None);
        assert_eq!(clip_to_box([0.5, -1.0], [0.5, 1.0], w), Some((0.5, 1.0)));
    }

    #[test]
    fn rings_at_0_30_over_a_disk_edge_are_supported() {
        let below = disk(5.0);
        let above = rings(4.9, 8.0, 0.30);
        let c = check_layer(
            &[&below],
            &above,
            filament_area(1.75),
            &CheckOptions::default(),
            false,
        );
        assert!(c.supported_mm / c.length_mm > 0.99, "{c:?}");
        assert!(c.in_air_mm < 1.0);
    }

    #[test]
    fn rings_at_0_45_are_in_air() {
        let below = disk(5.0);
        let above = rings(4.9, 8.0, 0.45);
        let c = check_layer(
            &[&below],
            &above,
            filament_area(1.75),
            &CheckOptions::default(),
            false,
        );
        // Only the first ring, on the disk's edge, is held.
        assert!(c.in_air_mm / c.length_mm > 0.7, "{c:?}");
    }

    #[test]
    fn a_first_layer_squashed_out_by_its_compensation_holds_a_wall_half_a_bead_past_it() {
        // The disk's outer bead is centred at 4.95 mm: a wall at 5.45 hangs 0.5 mm past it,
        // its inner edge 0.05 mm past the first layer's nominal bead.
        let fa = filament_area(1.75);
        let above = rings(5.45, 5.45, 0.45);
        let check = |spread: f64| {
            let mut below = disk(5.0);
            below.index = 0;
            below.spread = spread;
            check_layer(&[&below], &above, fa, &CheckOptions::default(), false)
        };
        let nominal = check(0.0);
        assert!(nominal.in_air_mm / nominal.length_mm > 0.95, "{nominal:?}");
        // PrusaSlicer's default compensation, 0.2 mm: the squashed bead reaches 5.375.
        let squashed = check(0.2);
        assert!(
            squashed.supported_mm / squashed.length_mm > 0.99,
            "{squashed:?}"
        );
    }

    #[test]
    fn bridge_over_a_gap_and_cantilever() {
        let fa = filament_area(1.75);
        let below = layer(
            1,
            vec![
                strand(vec![[0.0, 0.0], [5.0, 0.0]], 0.45),
                strand(vec![[15.0, 0.0], [20.0, 0.0]], 0.45),
            ],
        );
        let across = layer(2, vec![strand(vec![[0.0, 0.0], [20.0, 0.0]], 0.45)]);
        let c = check_layer(&[&below], &across, fa, &CheckOptions::default(), false);
        assert!(c.in_air_mm < 1e-9, "{c:?}");
        assert!((c.bridged_mm - 10.0).abs() < 1.0, "{c:?}");
        let cantilever = layer(2, vec![strand(vec![[0.0, 0.0], [45.0, 0.0]], 0.45)]);
        let below = layer(1, vec![strand(vec![[0.0, 0.0], [5.0, 0.0]], 0.45)]);
        let c = check_layer(&[&below], &cantilever, fa, &CheckOptions::default(), false);
        assert!((c.in_air_mm - 40.0).abs() < 1.0, "{c:?}");
        assert!((c.longest_in_air_mm - 40.0).abs() < 1.0);
    }

    #[test]
    fn a_path_kilometres_long_is_sampled_within_a_bound() {
        // Moves gone relative by a stray G91 drew strands kilometres long: sampled every
        // 0.1 mm, one layer held gigabytes of samples.
        let fa = filament_area(1.75);
        let below = layer(1, vec![strand(vec![[0.0, 0.0], [5.0, 0.0]], 0.45)]);
        let far = layer(2, vec![strand(vec![[0.0, 0.0], [0.0, 900_000.0]], 0.45)]);
        let c = check_layer(&[&below], &far, fa, &CheckOptions::default(), true);
        assert!(
            c.samples.len() <= MAX_PATH_SAMPLES as usize + 1,
            "{}",
            c.samples.len()
        );
        // Still measured: all of it but the first bead's length lies in air.
        assert!((c.in_air_mm - 900_000.0).abs() < 10.0, "{c:?}");
        // A path of ordinary length keeps the 0.1 mm step.
        let near = layer(2, vec![strand(vec![[0.0, 0.0], [20.0, 0.0]], 0.45)]);
        let c = check_layer(&[&below], &near, fa, &CheckOptions::default(), true);
        assert_eq!(c.samples.len(), 200);
    }

    #[test]
    fn a_normal_layer_has_density_one() {
        let paths: Vec<Path> = (0..20)
            .map(|i| {
                let y = i as f64 * (0.45 - 0.2 * (1.0 - std::f64::consts::FRAC_PI_4));
                strand(vec![[0.0, y], [20.0, y]], 0.45)
            })
            .collect();
        let c = check_layer(
            &[],
            &layer(0, paths),
            filament_area(1.75),
            &CheckOptions::default(),
            false,
        );
        assert!((c.density - 1.0).abs() < 0.05, "{}", c.density);
    }
}
