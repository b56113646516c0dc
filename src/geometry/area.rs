//! A layer's printed area: what the layer above can rest on.
//!
//! The footprint of a strand is its centerline buffered by half its width; the strands of parts
//! too far apart to touch are buffered separately, in parallel, and their footprints put side
//! by side (the union of disjoint shapes). A layer's printed area is the union of its
//! footprints with the gaps *inside* the part closed: the air between
//! sparse-infill lines, or between an inner perimeter and the infill, is not air for the layer
//! above (a slicer bridges it on purpose). Real holes of the part stay open.
//!
//! Which holes are infill gaps: when the file tags sparse infill, it is left out of the
//! footprint altogether, and a hole that contains sparse infill is closed (the region it fills
//! becomes one hole walled by inner perimeters). When the file tells external perimeters apart,
//! a hole is also closed unless its edge runs along an external perimeter (a hole in a part is
//! always walled by one). Holes narrower than `min_hole` are closed whatever walls them.
//! Without roles, every strand is buffered and a hole is closed when it is narrower than
//! `gap_close` (no disc of that diameter fits).

use std::collections::BTreeMap;

use geo::algorithm::buffer::{BufferStyle, LineCap, LineJoin};
use geo::{
    coord, orient::Direction, unary_union, Area, BooleanOps, BoundingRect, Buffer, Contains,
    LineString, MultiLineString, MultiPolygon, Orient, Point, Polygon,
};

use rayon::prelude::*;

use crate::layers::{Layer, Path, Role};

use super::offset;

/// How a printed area is computed.
#[derive(Debug, Clone)]
pub struct AreaOptions {
    /// Without roles: holes narrower than this (mm) are infill gaps and get closed.
    pub gap_close: f64,
    /// Holes no wider than this (mm) are closed whatever walls them: nothing the layer above
    /// prints across them needs help.
    pub min_hole: f64,
    /// The slicer prints no sparse infill (`fill_density = 0%`): a part's inside with no
    /// infill strand in it is air, not a gap the infill rule could not see into.
    pub hollow: bool,
}

impl Default for AreaOptions {
    fn default() -> Self {
        AreaOptions {
            gap_close: 6.0,
            min_hole: 1.0,
            hollow: false,
        }
    }
}

/// Join and cap arcs: segment length / radius (radians).
pub(super) const ROUND_ANGLE: f64 = 0.35;

/// Average segment length (mm) under which a strand's polyline is simplified before it is
/// buffered ([`Strands::of_lines`]).
const DENSE_SPACING: f64 = 0.02;
/// How far (mm) that simplification may move a dense polyline.
const DENSE_SIMPLIFY: f64 = 0.001;

/// Side (mm) of the cells [`Strands::crowded`] counts.
const CROWD_CELL: f64 = 1.0;

/// How many times the area of the cells they pass through strands' beads may cover before
/// they are buffered by Clipper instead (a solid layer covers its cells about once).
const CROWDED: f64 = 4.0;

/// Most cells a side of the raster a crowded layer's footprint is drawn on
/// ([`Strands::buffer_crowded`]).
const RASTER_CELLS: usize = 4096;

/// Finest cell (mm) of that raster.
const RASTER_CELL: f64 = 0.05;

/// The first cell at or after `from` of a raster row (`nx` cells, one bit each) whose bit is
/// `set`, or `nx`: a word at a time, so an empty row costs `nx / 64` steps.
fn next_cell(row: &[u64], from: usize, nx: usize, set: bool) -> usize {
    let word = |w: usize| if set { row[w] } else { !row[w] };
    let mut w = from / 64;
    if w >= row.len() {
        return nx;
    }
    let mut bits = word(w) & (!0u64 << (from % 64));
    loop {
        if bits != 0 {
            return (w * 64 + bits.trailing_zeros() as usize).min(nx);
        }
        w += 1;
        if w >= row.len() {
            return nx;
        }
        bits = word(w);
    }
}

/// Runs of cells of a raster, row by row: `(row, a, b)` for the cells `[a, b)`, sorted, and
/// where each row's runs start in that list.
#[derive(Debug, Default)]
struct RowRuns {
    runs: Vec<(usize, usize, usize)>,
    /// Row `r` holds `runs[first[r]..first[r + 1]]`.
    first: Vec<usize>,
}

impl RowRuns {
    /// Starts the next row; its runs are pushed after.
    fn new_row(&mut self) {
        if self.first.is_empty() {
            self.first.push(0);
        }
        self.first.push(self.runs.len());
    }

    fn push(&mut self, a: usize, b: usize) {
        let r = self.rows() - 1;
        self.runs.push((r, a, b));
        if let Some(end) = self.first.last_mut() {
            *end = self.runs.len();
        }
    }

    fn rows(&self) -> usize {
        self.first.len().saturating_sub(1)
    }

    /// The indices of row `r`'s runs.
    fn row(&self, r: usize) -> std::ops::Range<usize> {
        self.first[r]..self.first[r + 1]
    }
}

/// The cells of an `nx` x `ny` raster (rows of `stride` words, a bit per cell) that are set
/// or empty but enclosed, i.e. not joined to the raster's edge by empty cells: per row, its
/// runs `[a, b)`. Found on runs of empty cells, not cells: two runs of adjacent rows meet
/// where they share a column, and the runs joined to the edge are flooded from the edge
/// rows and the runs touching the side columns. Time and memory follow the runs (an empty
/// row is one), not the cells: a raster stretched over metres by a damaged file's far-out
/// strands is mostly empty rows.
fn enclosed_runs(bits: &[u64], nx: usize, ny: usize, stride: usize) -> RowRuns {
    let mut empty = RowRuns::default();
    for r in 0..ny {
        empty.new_row();
        let row = &bits[r * stride..(r + 1) * stride];
        let mut c = 0;
        while c < nx {
            let a = next_cell(row, c, nx, false);
            if a >= nx {
                break;
            }
            let b = next_cell(row, a, nx, true);
            empty.push(a, b);
            c = b;
        }
    }
    let runs = &empty.runs;
    let mut outside = vec![false; runs.len()];
    let mut stack: Vec<usize> = Vec::new();
    for (i, &(r, a, b)) in runs.iter().enumerate() {
        if r == 0 || r + 1 == ny || a == 0 || b == nx {
            outside[i] = true;
            stack.push(i);
        }
    }
    while let Some(i) = stack.pop() {
        let (r, a, b) = runs[i];
        for nr in [r.wrapping_sub(1), r + 1] {
            if nr >= ny {
                continue;
            }
            let row = empty.row(nr);
            // Runs of a row are sorted and disjoint: those sharing a column with [a, b).
            let mut j = row.start + runs[row.clone()].partition_point(|&(_, _, e)| e <= a);
            while j < row.end && runs[j].1 < b {
                if !outside[j] {
                    outside[j] = true;
                    stack.push(j);
                }
                j += 1;
            }
        }
    }
    // What lies between each row's outside runs.
    let mut kept = RowRuns::default();
    for r in 0..ny {
        kept.new_row();
        let mut c = 0;
        for i in empty.row(r) {
            if outside[i] {
                let (_, a, b) = runs[i];
                if a > c {
                    kept.push(c, a);
                }
                c = b;
            }
        }
        if c < nx {
            kept.push(c, nx);
        }
    }
    kept
}

/// The outline of a raster's runs (per row, `[a, b)` in cells, sorted; `x(c)` and `y(r)`
/// the cell edges' coordinates). Runs of a row that meet one run of the next row, and only
/// it, sharing a column, are a strip, drawn at once as a staircase; strips that touch (a
/// corner will do) are one group, joined by Clipper. Clipper alone took 30 ms for one pile of
/// 4 000 rows (a rectangle a row), and a damaged file has hundreds of such layers.
fn runs_outline(
    kept: &RowRuns,
    x: impl Fn(usize) -> f64,
    y: impl Fn(usize) -> f64,
) -> MultiPolygon<f64> {
    use geo_clipper::Clipper;
    let (runs, first) = (&kept.runs, &kept.first);
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    let mut parent: Vec<usize> = (0..runs.len()).collect();
    let (mut ups, mut downs) = (vec![0u32; runs.len()], vec![0u32; runs.len()]);
    let mut below = vec![usize::MAX; runs.len()];
    for r in 1..kept.rows() {
        let (mut i, mut j) = (first[r - 1], first[r]);
        while i < first[r] && j < first[r + 1] {
            let ((_, a, b), (_, c, d)) = (runs[i], runs[j]);
            if c <= b && a <= d {
                let (p, q) = (root(&mut parent, i), root(&mut parent, j));
                parent[p.max(q)] = p.min(q);
            }
            if c < b && a < d {
                ups[i] += 1;
                downs[j] += 1;
                below[j] = i;
            }
            if b <= d {
                i += 1;
            } else {
                j += 1;
            }
        }
    }
    // Strips, each a list of runs from the bottom row up, by group.
    let mut strip_of = vec![usize::MAX; runs.len()];
    let mut strips: Vec<Vec<usize>> = Vec::new();
    for n in 0..runs.len() {
        strip_of[n] = if downs[n] == 1 && ups[below[n]] == 1 {
            strip_of[below[n]]
        } else {
            strips.push(Vec::new());
            strips.len() - 1
        };
        strips[strip_of[n]].push(n);
    }
    let mut groups: BTreeMap<usize, Vec<Polygon<f64>>> = BTreeMap::new();
    for strip in strips {
        // Up the right edges, down the left ones: counter-clockwise, and simple because each
        // run shares a column with the next.
        let mut ring: Vec<geo::Coord<f64>> = Vec::with_capacity(4 * strip.len() + 1);
        for &n in &strip {
            let (r, _, b) = runs[n];
            ring.push(coord! {x: x(b), y: y(r)});
            ring.push(coord! {x: x(b), y: y(r + 1)});
        }
        for &n in strip.iter().rev() {
            let (r, a, _) = runs[n];
            ring.push(coord! {x: x(a), y: y(r + 1)});
            ring.push(coord! {x: x(a), y: y(r)});
        }
        // Points where the edge goes straight on are dropped.
        let mut clean: Vec<geo::Coord<f64>> = Vec::with_capacity(ring.len() + 1);
        let m = ring.len();
        for k in 0..m {
            let (p, q, t) = (ring[(k + m - 1) % m], ring[k], ring[(k + 1) % m]);
            let cross = (q.x - p.x) * (t.y - q.y) - (q.y - p.y) * (t.x - q.x);
            if cross != 0.0 {
                clean.push(q);
            }
        }
        let group = root(&mut parent, strip[0]);
        groups
            .entry(group)
            .or_default()
            .push(Polygon::new(LineString::new(clean), Vec::new()));
    }
    let mut joined = Vec::new();
    for (_, polygons) in groups {
        if polygons.len() == 1 {
            joined.extend(polygons);
        } else {
            let polygons = MultiPolygon::new(polygons);
            joined.extend(
                Clipper::union(
                    &polygons,
                    &MultiPolygon::new(Vec::new()),
                    super::CLIPPER_SCALE,
                )
                .0,
            );
        }
    }
    MultiPolygon::new(joined)
}

/// Where the line `y = yc` meets the points within `half` of the segment `a`-`b`: the x
/// interval, or `None`. The capsule is convex, so the interval runs from the least to the
/// greatest x its pieces (the two end discs, the band between them) meet the line at.
fn capsule_row(a: [f64; 2], b: [f64; 2], half: f64, yc: f64) -> Option<(f64, f64)> {
    let (mut xl, mut xr) = (f64::INFINITY, f64::NEG_INFINITY);
    for p in [a, b] {
        let dy = yc - p[1];
        if dy.abs() <= half {
            let dx = (half * half - dy * dy).sqrt();
            xl = xl.min(p[0] - dx);
            xr = xr.max(p[0] + dx);
        }
    }
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let len = dx.hypot(dy);
    if len > 0.0 {
        let n = [-dy / len * half, dx / len * half];
        // The band's four edges: the segment shifted by +-n, and the ends' cross lines.
        let corners = [
            [a[0] + n[0], a[1] + n[1]],
            [b[0] + n[0], b[1] + n[1]],
            [b[0] - n[0], b[1] - n[1]],
            [a[0] - n[0], a[1] - n[1]],
        ];
        for i in 0..4 {
            let (p, q) = (corners[i], corners[(i + 1) % 4]);
            if (p[1] - yc) * (q[1] - yc) <= 0.0 && p[1] != q[1] {
                let x = p[0] + (yc - p[1]) / (q[1] - p[1]) * (q[0] - p[0]);
                xl = xl.min(x);
                xr = xr.max(x);
            }
        }
    }
    (xl <= xr).then_some((xl, xr))
}

/// Cells covered over [`CROWDED`] times by beads that make a layer crowded wherever its
/// other strands run ([`Strands::crowded`]).
const CROWDED_CELLS: usize = 16;

/// Most cell visits [`Strands::crowded`] makes before it calls strands crowded.
const MAX_CROWD_VISITS: usize = 5_000_000;

/// The centerlines a footprint is buffered from, by width: everything a footprint depends
/// on. Two layers with equal `Strands` (a vertical wall repeats its perimeters exactly) have
/// the same footprint, computed once.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Strands(BTreeMap<i64, Vec<LineString<f64>>>);

impl Strands {
    pub fn of<'a>(paths: impl IntoIterator<Item = &'a Path>) -> Strands {
        Strands::of_lines(paths.into_iter().map(|p| (&p.points[..], p.width)))
    }

    /// Strands from polylines and their bead widths.
    pub fn of_lines<'a>(lines: impl IntoIterator<Item = (&'a [[f64; 2]], f64)>) -> Strands {
        // One buffer call per width: geo buffers a MultiLineString at one distance.
        let mut by_width: BTreeMap<i64, Vec<LineString<f64>>> = BTreeMap::new();
        for (points, width) in lines {
            if points.len() < 2 || !(width > 0.0 && width < 50.0) {
                continue;
            }
            let mut pts: Vec<geo::Coord<f64>> = Vec::with_capacity(points.len());
            for q in points {
                let c = coord! {x: q[0], y: q[1]};
                if pts.last().is_none_or(|l: &geo::Coord<f64>| {
                    (l.x - c.x).abs() > 1e-7 || (l.y - c.y).abs() > 1e-7
                }) {
                    pts.push(c);
                }
            }
            if pts.len() < 2 {
                continue;
            }
            let mut line = LineString::new(pts);
            // A polyline of points closer than DENSE_SPACING on average (a 40 mm circle in
            // 100 000 segments, an STL of fine facets) is simplified by a micrometre first:
            // every segment's round cap crossed dozens of its neighbours' and the buffer's
            // crossings grew as their square (7 s for one such ring). A slicer's polylines
            // are far sparser and are buffered as written.
            if line.0.len() > 2 {
                let length: f64 = line
                    .0
                    .windows(2)
                    .map(|w| (w[1].x - w[0].x).hypot(w[1].y - w[0].y))
                    .sum();
                if length < DENSE_SPACING * (line.0.len() - 1) as f64 {
                    line = geo::Simplify::simplify(&line, DENSE_SIMPLIFY);
                }
            }
            let key = (width * 1000.0).round() as i64;
            by_width.entry(key).or_default().push(line);
        }
        Strands(by_width)
    }

    /// Union of the strands' footprints (centerline buffered by width / 2, round caps and
    /// joins).
    pub fn buffer(&self) -> MultiPolygon<f64> {
        match self.split() {
            // The parts of a plate, each buffered alone and on all cores: the union of
            // footprints that cannot meet is their concatenation.
            Some(groups) => {
                let parts: Vec<MultiPolygon<f64>> =
                    groups.par_iter().map(Strands::buffer_whole).collect();
                MultiPolygon::new(parts.into_iter().flat_map(|m| m.0).collect())
            }
            None => self.buffer_whole(),
        }
    }

    fn buffer_whole(&self) -> MultiPolygon<f64> {
        if self.crowded() {
            return self.buffer_crowded();
        }
        let mut parts: Vec<MultiPolygon<f64>> = Vec::new();
        for (key, lines) in &self.0 {
            let half = *key as f64 / 2000.0;
            let style = BufferStyle::new(half)
                .line_cap(LineCap::Round(ROUND_ANGLE))
                .line_join(LineJoin::Round(ROUND_ANGLE));
            parts.push(MultiLineString::new(lines.clone()).buffer_with_style(style));
        }
        match parts.len() {
            0 => MultiPolygon::new(Vec::new()),
            1 => parts.pop().unwrap_or_else(|| MultiPolygon::new(Vec::new())),
            _ => unary_union(parts.iter().flat_map(|m| m.0.iter())),
        }
    }

    /// Whether the strands pile on each other: their beads' area more than [`CROWDED`] times
    /// that of the [`CROWD_CELL`] cells they pass through. Only a damaged file makes such a
    /// layer (several layers' strands in one, found by fuzzing), and geo's stroke buffer meets
    /// every crossing of its strands one by one: minutes for a 300 kB file.
    fn crowded(&self) -> bool {
        // Bead area by cell: each sample of a segment brings its share.
        let mut cells: std::collections::HashMap<(i64, i64), f64> = Default::default();
        let (mut beads, mut visits) = (0.0, 0usize);
        for (key, lines) in &self.0 {
            let w = *key as f64 / 1000.0;
            for l in lines {
                for s in l.0.windows(2) {
                    let (a, b) = (s[0], s[1]);
                    let len = (b.x - a.x).hypot(b.y - a.y);
                    if !len.is_finite() {
                        return true;
                    }
                    beads += len * w;
                    let n = (len / (CROWD_CELL / 2.0)).ceil() as usize;
                    visits += n + 1;
                    if visits > MAX_CROWD_VISITS {
                        return true;
                    }
                    let share = len * w / (n + 1) as f64;
                    for k in 0..=n {
                        let t = if n == 0 { 0.0 } else { k as f64 / n as f64 };
                        let (x, y) = (a.x + t * (b.x - a.x), a.y + t * (b.y - a.y));
                        *cells
                            .entry((
                                (x / CROWD_CELL).floor() as i64,
                                (y / CROWD_CELL).floor() as i64,
                            ))
                            .or_default() += share;
                    }
                }
            }
        }
        let cell_area = CROWD_CELL * CROWD_CELL;
        // A pile somewhere counts even when long strands elsewhere thin the layer's mean
        // out (a scribble with one move 97 m away and back: its exact buffer took 18 GB).
        let piled = cells.values().filter(|&&a| a > CROWDED * cell_area).count();
        beads > CROWDED * cells.len() as f64 * cell_area || piled >= CROWDED_CELLS
    }

    /// [`Strands::buffer_whole`] for crowded strands (only a damaged or hostile file piles
    /// strands so): drawn on a raster of at most [`RASTER_CELLS`] cells a side, each cell
    /// whose centre lies within a strand's half width set, then the cells' runs joined into
    /// polygons. Any exact buffer meets every crossing of the strands: Clipper's sweep took
    /// 8 s for a layer of 50 000 short strokes wandering over each other, minutes and 3 GB
    /// for 2 million; the raster takes time in proportion to the beads' area and memory to
    /// its cells (2 MB). The outline is exact to a cell (0.05 mm on a plate).
    fn buffer_crowded(&self) -> MultiPolygon<f64> {
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        let mut reach: f64 = 0.0;
        for (key, lines) in &self.0 {
            let half = *key as f64 / 2000.0;
            if !(half > 0.0 && half.is_finite()) {
                continue;
            }
            reach = reach.max(half);
            for c in lines.iter().flat_map(|l| l.0.iter()) {
                if c.x.is_finite() && c.y.is_finite() {
                    lo = [lo[0].min(c.x), lo[1].min(c.y)];
                    hi = [hi[0].max(c.x), hi[1].max(c.y)];
                }
            }
        }
        if !(lo[0] <= hi[0] && lo[1] <= hi[1]) {
            return MultiPolygon::new(Vec::new());
        }
        let (lo, hi) = (
            [lo[0] - reach, lo[1] - reach],
            [hi[0] + reach, hi[1] + reach],
        );
        let extent = (hi[0] - lo[0]).max(hi[1] - lo[1]);
        let cell = RASTER_CELL.max(extent / RASTER_CELLS as f64);
        if !cell.is_finite() {
            return MultiPolygon::new(Vec::new());
        }
        let nx = (((hi[0] - lo[0]) / cell).ceil() as usize).clamp(1, RASTER_CELLS);
        let ny = (((hi[1] - lo[1]) / cell).ceil() as usize).clamp(1, RASTER_CELLS);
        let stride = nx.div_ceil(64);
        let mut bits = vec![0u64; stride * ny];
        for (key, lines) in &self.0 {
            let half = *key as f64 / 2000.0;
            if !(half > 0.0 && half.is_finite()) {
                continue;
            }
            for l in lines {
                for seg in l.0.windows(2) {
                    let (a, b) = ([seg[0].x, seg[0].y], [seg[1].x, seg[1].y]);
                    if !a.iter().chain(b.iter()).all(|v| v.is_finite()) {
                        continue;
                    }
                    let y0 = a[1].min(b[1]) - half;
                    let y1 = a[1].max(b[1]) + half;
                    let r0 = (((y0 - lo[1]) / cell - 0.5).ceil().max(0.0)) as usize;
                    let r1 = ((((y1 - lo[1]) / cell - 0.5).floor()) as usize).min(ny - 1);
                    for r in r0..=r1 {
                        let yc = lo[1] + (r as f64 + 0.5) * cell;
                        let Some((xl, xr)) = capsule_row(a, b, half, yc) else {
                            continue;
                        };
                        let c0 = (((xl - lo[0]) / cell - 0.5).ceil().max(0.0)) as usize;
                        let c1 = (((xr - lo[0]) / cell - 0.5).floor().max(-1.0)) as isize;
                        let c1 = (c1.min(nx as isize - 1)).max(-1);
                        for c in c0 as isize..=c1 {
                            let c = c as usize;
                            bits[r * stride + c / 64] |= 1 << (c % 64);
                        }
                    }
                }
            }
        }
        // The empty cells reached from the raster's edge are outside; the rest are holes in
        // the pile, filled: a wandering stroke leaves thousands of specks of holes, and
        // every boolean after pays for each hole against each outline (minutes more).
        let kept = enclosed_runs(&bits, nx, ny, stride);
        let joined = runs_outline(
            &kept,
            |c| lo[0] + c as f64 * cell,
            |r| lo[1] + r as f64 * cell,
        );
        // The cells' stairs simplified to within a cell: every offset after would round
        // each step's corner (planning a region of such stairs took minutes).
        geo::Simplify::simplify(&joined, cell)
    }

    /// Groups of strands whose footprints cannot meet: no strand's box, grown by more than
    /// its half width, meets a box of another group. `None` when there is one group.
    fn split(&self) -> Option<Vec<Strands>> {
        let mut items: Vec<(i64, usize)> = Vec::new();
        let mut boxes: Vec<super::Box2> = Vec::new();
        for (key, lines) in &self.0 {
            // Round caps and joins are polygons that may reach a little past the half width.
            let reach = *key as f64 / 2000.0 * 1.1 + 1e-3;
            for (i, l) in lines.iter().enumerate() {
                let b = l.bounding_rect()?;
                if ![b.min().x, b.min().y, b.max().x, b.max().y]
                    .iter()
                    .all(|v| v.is_finite())
                {
                    return None;
                }
                items.push((*key, i));
                boxes.push((
                    [b.min().x - reach, b.min().y - reach],
                    [b.max().x + reach, b.max().y + reach],
                ));
            }
        }
        let groups = super::box_groups(&boxes);
        if groups.len() <= 1 {
            return None;
        }
        Some(
            groups
                .iter()
                .map(|g| {
                    let mut s = Strands::default();
                    for &n in g {
                        let (key, i) = items[n];
                        s.0.entry(key).or_default().push(self.0[&key][i].clone());
                    }
                    s
                })
                .collect(),
        )
    }
}

/// What a layer prints after a rewrite: `area` without the rewritten `zones`, plus the
/// footprint of the strands written there (polylines with their widths). The layer above is
/// planned on this, not on the layer as sliced: a perimeter pulled in moves its support.
pub fn rewritten_area<'a>(
    area: &MultiPolygon<f64>,
    zones: &MultiPolygon<f64>,
    strands: impl IntoIterator<Item = (&'a [[f64; 2]], f64)>,
) -> MultiPolygon<f64> {
    let written = Strands::of_lines(strands).buffer();
    BooleanOps::union(&BooleanOps::difference(area, zones), &written)
}

/// Union of the strands' footprints (centerline buffered by width / 2, round caps and joins).
pub fn footprint<'a>(paths: impl IntoIterator<Item = &'a Path>) -> MultiPolygon<f64> {
    Strands::of(paths).buffer()
}

/// [`footprint`], or `None` where the strands pile on each other ([`Strands::crowded`]: a
/// damaged file; the deposition check reports no density for such a layer).
pub fn footprint_if_spread<'a>(
    paths: impl IntoIterator<Item = &'a Path>,
) -> Option<MultiPolygon<f64>> {
    let strands = Strands::of(paths);
    (!strands.crowded()).then(|| strands.buffer())
}

/// Strands that hold up the layer above: the part and its support, not skirt or priming.
fn supports(role: Role) -> bool {
    role.is_part() || matches!(role, Role::Support | Role::SupportInterface)
}

/// Roles whose strands outline a layer told in walls and infill ([`outline_strands`]).
pub(super) fn is_outline(role: Role) -> bool {
    supports(role) && !interior(role)
}

/// Roles printed inside a part's perimeters: evidence of what the perimeters enclose.
pub(super) fn interior(role: Role) -> bool {
    matches!(
        role,
        Role::Infill
            | Role::SolidInfill
            | Role::TopSolid
            | Role::BridgeInfill
            | Role::InternalBridge
    )
}

/// Midpoints of the segments of the paths `keep` selects, sorted by x for range queries.
pub(super) fn midpoints(layer: &Layer, keep: impl Fn(Role) -> bool) -> Vec<[f64; 2]> {
    let mut v: Vec<[f64; 2]> = layer
        .paths
        .iter()
        .filter(|p| keep(p.role))
        .flat_map(|p| {
            p.points
                .windows(2)
                .map(|w| [(w[0][0] + w[1][0]) / 2.0, (w[0][1] + w[1][1]) / 2.0])
        })
        .collect();
    v.sort_unstable_by(|a, b| a[0].total_cmp(&b[0]));
    v
}

/// What a layer tells about its outline, which decides how its printed area is made.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Outline {
    /// External perimeters told apart: holes are decided by infill and walls.
    Walls,
    /// Sparse infill tagged, external perimeters not told apart (Slic3r).
    Infill,
    /// No roles to go by.
    Bare,
}

fn outline(layer: &Layer) -> Outline {
    if layer
        .paths
        .iter()
        .any(|p| matches!(p.role, Role::ExternalPerimeter | Role::OverhangPerimeter))
    {
        Outline::Walls
    } else if layer.paths.iter().any(|p| p.role == Role::Infill) {
        Outline::Infill
    } else {
        Outline::Bare
    }
}

/// The strands whose footprint outlines the layer's printed area.
pub fn outline_strands(layer: &Layer) -> Strands {
    match outline(layer) {
        // Perimeters and the other strands outline the part; what infill fills is closed in
        // by hole filling instead of being buffered strand by strand (the costly part).
        Outline::Walls => walls_and_joins(layer, false),
        Outline::Infill => Strands::of(
            layer
                .paths
                .iter()
                .filter(|p| supports(p.role) && p.role != Role::Infill),
        ),
        Outline::Bare => Strands::of(layer.paths.iter().filter(|p| supports(p.role))),
    }
}

/// Longest gap (mm) between two walls printed one after the other that is taken as one wall
/// interrupted: Cura coasts over the end of a bridged wall (`bridge_wall_coast`) and so
/// leaves a loop open by a millimetre or two, which would leave the part's outline unclosed.
const WALL_JOIN: f64 = 2.5;

/// A wall loop is closed across its seam only where the gap is at most this share of its
/// length: the ends of an open wall (a thin fin's single line) lie far apart.
const SEAM_SHARE: f64 = 0.2;

fn is_wall(role: Role) -> bool {
    matches!(
        role,
        Role::ExternalPerimeter | Role::Perimeter | Role::OverhangPerimeter
    )
}

/// Short strands that join consecutive walls of one object across a gap up to
/// [`WALL_JOIN`], and close a wall loop left open by that much at its seam (Cura's coasting
/// ends every wall loop 1.6 mm short: with the seams aligned, a ring's walls all open at the
/// same place, the ring read as a C, and the hole it walls filled), for the outline only
/// (nothing is printed there; the nozzle's pressure lays the coasted end).
///
/// A wall is a run of wall paths each starting where the one before it ended (PrusaSlicer
/// splits a wall wherever its width changes): only the run's own two ends are open. Joining
/// the ends of one piece of a run, or a closed run to the wall printed next, ran across the
/// hole such a wall winds round (an Arachne perimeter threading between a perforated
/// plate's holes; a hole's wall followed by the perimeter beside it): a phantom strip of
/// support over the hole.
pub(super) fn wall_joins(layer: &Layer) -> Vec<Path> {
    let paths = &layer.paths;
    let dist = |a: [f64; 2], b: [f64; 2]| ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt();
    // Whether wall `q` starts where wall `p` of the same object ends.
    let continues = |p: &Path, q: &Path| {
        is_wall(p.role)
            && is_wall(q.role)
            && p.object == q.object
            && matches!((p.points.last(), q.points.first()), (Some(&e), Some(&s)) if dist(e, s) <= 1e-6)
    };
    let mut joins = Vec::new();
    // The first path of the run the current wall belongs to, and the run's length so far.
    let mut first = 0;
    let mut len = 0.0;
    for (i, p) in paths.iter().enumerate() {
        if !is_wall(p.role) {
            continue;
        }
        if i == 0 || !continues(&paths[i - 1], p) {
            first = i;
            len = 0.0;
        }
        len += p.length();
        let next = paths.get(i + 1);
        if next.is_some_and(|q| continues(p, q)) {
            continue;
        }
        let (Some(&start), Some(&end)) = (paths[first].points.first(), p.points.last()) else {
            continue;
        };
        let gap = dist(end, start);
        let points: usize = paths[first..=i].iter().map(|q| q.points.len()).sum();
        let closed = gap <= 1e-6 && points > 2;
        let seam = gap > 1e-6 && gap <= WALL_JOIN && gap <= SEAM_SHARE * len;
        if seam {
            joins.push(join(p, end, start, p.width));
        }
        // A wall broken off (Cura's coasting over a bridged wall's end) is joined to the
        // wall printed next; a loop is whole.
        let Some(q) = next else { continue };
        if closed || seam || !is_wall(q.role) || q.object != p.object {
            continue;
        }
        if let Some(&s) = q.points.first() {
            let g = dist(end, s);
            if g > 1e-6 && g <= WALL_JOIN && goes_on(p, q, end, s) {
                joins.push(join(p, end, s, p.width.min(q.width)));
            }
        }
    }
    joins
}

/// Least cosine between a join and the wall pieces it joins ([`goes_on`]): 60 degrees, what
/// a join over 1.6 mm of coasting turns on a wall of 0.8 mm radius.
const GOES_ON_COS: f64 = 0.5;

/// Whether the join from `p`'s end `e` to `q`'s start `s` goes on the way `p` ends and `q`
/// starts: a wall coasted to a stop and taken up again further along. Two short pieces of
/// an Arachne perimeter printed one after the other at a corner lie 2 mm apart across a
/// hole, turned back on each other.
fn goes_on(p: &Path, q: &Path, e: [f64; 2], s: [f64; 2]) -> bool {
    let dir = |a: [f64; 2], b: [f64; 2]| {
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let l = (dx * dx + dy * dy).sqrt();
        (l > 1e-9).then(|| [dx / l, dy / l])
    };
    let n = p.points.len();
    let (Some(j), Some(a), Some(b)) = (
        dir(e, s),
        (n >= 2).then(|| dir(p.points[n - 2], e)).flatten(),
        (q.points.len() >= 2).then(|| dir(s, q.points[1])).flatten(),
    ) else {
        return false;
    };
    j[0] * a[0] + j[1] * a[1] >= GOES_ON_COS && j[0] * b[0] + j[1] * b[1] >= GOES_ON_COS
}

/// Farthest (in widths of the wider wall) the open ends of two walls lie apart and are
/// joined whatever order they were printed in ([`end_joins`]).
const END_JOIN: f64 = 1.5;

/// Joins each open end of a wall to the nearest open end of another wall of the same object
/// within [`END_JOIN`] widths. Where poa's moved perimeter meets the slicer's perimeter it
/// kept, their ends lie half a millimetre apart; joined only when printed one after the
/// other, the outline of a hull's bow was closed or left open by the slit between them
/// depending on the order poa laid its strands in, and the layer above found a region in
/// the pocket behind the slit. Closed loops (their two ends together) take no part.
fn end_joins(layer: &Layer, joins: &mut Vec<Path>) {
    // (x, y, path, width) of every open wall end.
    let mut ends: Vec<([f64; 2], usize, f64)> = Vec::new();
    for (i, p) in layer.paths.iter().enumerate() {
        if !is_wall(p.role) || p.points.len() < 2 || !(p.width > 0.0 && p.width < 50.0) {
            continue;
        }
        let (a, b) = (p.points[0], p.points[p.points.len() - 1]);
        if (a[0] - b[0]).hypot(a[1] - b[1]) <= 1e-6 {
            continue;
        }
        for e in [a, b] {
            if e[0].is_finite() && e[1].is_finite() {
                ends.push((e, i, p.width));
            }
        }
    }
    if ends.len() < 2 {
        return;
    }
    ends.sort_unstable_by(|x, y| x.0[0].total_cmp(&y.0[0]));
    let widest = ends.iter().map(|e| e.2).fold(0.0, f64::max);
    let reach = END_JOIN * widest;
    // The nearest open end of another wall of the object, looked for on both sides in x.
    let nearest = |k: usize| -> Option<usize> {
        let (q, i, wq) = ends[k];
        let mut best: Option<(f64, usize)> = None;
        let lo = ends[..k].partition_point(|e| e.0[0] < q[0] - reach);
        for (j, &(r, pj, wr)) in ends.iter().enumerate().skip(lo) {
            if r[0] > q[0] + reach {
                break;
            }
            if pj == i || layer.paths[pj].object != layer.paths[i].object {
                continue;
            }
            let d = (r[0] - q[0]).hypot(r[1] - q[1]);
            if d > 1e-6 && d <= END_JOIN * wq.max(wr) && best.is_none_or(|b| d < b.0) {
                best = Some((d, j));
            }
        }
        best.map(|b| b.1)
    };
    let near: Vec<Option<usize>> = (0..ends.len()).map(nearest).collect();
    for (k, n) in near.iter().enumerate() {
        let Some(j) = *n else { continue };
        // Two ends that choose each other are joined once.
        if near[j] == Some(k) && j < k {
            continue;
        }
        let ((q, i, wq), (r, _, wr)) = (ends[k], ends[j]);
        joins.push(join(&layer.paths[i], q, r, wq.min(wr)));
    }
}

/// A join from `from` to `to` with the attributes of `wall` (whose strands it does not
/// copy: this runs for every loop of every layer the proof reads).
fn join(wall: &Path, from: [f64; 2], to: [f64; 2], width: f64) -> Path {
    Path {
        role: wall.role,
        width,
        height: wall.height,
        z: wall.z,
        object: wall.object,
        tool: wall.tool,
        points: vec![from, to],
        seg_line: vec![0],
        seg_e: vec![0.0],
        feed: wall.feed,
    }
}

/// The area a layer covers for the layer above, holes that are infill gaps closed.
pub fn printed_area(layer: &Layer, opts: &AreaOptions) -> MultiPolygon<f64> {
    area_from_footprint(layer, outline_strands(layer).buffer(), opts)
}

/// [`printed_area`] of a layer poa rewrote, whose strands poa laid in an order of its own
/// choosing: walls whose open ends meet are joined whatever order they were printed in
/// ([`end_joins`]), so that the order poa picks does not change the outline the layer above
/// is searched on.
pub fn printed_area_any_order(layer: &Layer, opts: &AreaOptions) -> MultiPolygon<f64> {
    if outline(layer) != Outline::Walls {
        return printed_area(layer, opts);
    }
    area_from_footprint(layer, walls_and_joins(layer, true).buffer(), opts)
}

/// A layer's outline strands when it tells walls apart, with the joins across interrupted
/// walls ([`wall_joins`]; with `any_order`, [`end_joins`] too).
fn walls_and_joins(layer: &Layer, any_order: bool) -> Strands {
    let mut walls: Vec<&Path> = layer.paths.iter().filter(|p| is_outline(p.role)).collect();
    let mut joins = wall_joins(layer);
    if any_order {
        end_joins(layer, &mut joins);
    }
    walls.extend(joins.iter());
    Strands::of(walls)
}

/// [`printed_area`] from the footprint of the layer's [`outline_strands`].
pub fn area_from_footprint(
    layer: &Layer,
    fp: MultiPolygon<f64>,
    opts: &AreaOptions,
) -> MultiPolygon<f64> {
    match outline(layer) {
        Outline::Walls => {
            if layer.paths.iter().any(|p| is_support(p.role)) {
                return with_support(layer, opts);
            }
            let walls: Vec<&Path> = layer
                .paths
                .iter()
                .filter(|p| matches!(p.role, Role::ExternalPerimeter | Role::OverhangPerimeter))
                .collect();
            // In a hollow part (no sparse infill) solid infill holds its own footprint and no
            // more: a strip of it along one wall of a hollow plate (where a fillet starts on
            // its side) closed the plate's whole inside, which got loops over air (13 of
            // them, 30 mm in air where the slicer left 1.6). Sparse infill still closes the
            // hole it lies in (an object whose own settings give it infill).
            let fp = if opts.hollow {
                let solid: Vec<&Path> = layer
                    .paths
                    .iter()
                    .filter(|p| interior(p.role) && p.role != Role::Infill)
                    .collect();
                if solid.is_empty() {
                    fp
                } else {
                    BooleanOps::union(&fp, &footprint(solid))
                }
            } else {
                fp
            };
            let inside = if opts.hollow {
                midpoints(layer, |r| r == Role::Infill)
            } else {
                midpoints(layer, interior)
            };
            // Islands that may stand in another's hole (a post inside a ring): their own
            // infill says nothing about the hole round them.
            let islands: Vec<(geo::Rect<f64>, Polygon<f64>)> =
                if fp.0.len() >= 2 && fp.0.iter().any(|q| !q.interiors().is_empty()) {
                    fp.0.iter()
                        .filter_map(|q| {
                            let b = q.exterior().bounding_rect()?;
                            Some((b, Polygon::new(q.exterior().clone(), Vec::new())))
                        })
                        .collect()
                } else {
                    Vec::new()
                };
            // Most layers have no hole that the infill test leaves undecided: build the wall
            // zone only for the first one that needs it.
            let mut wall_fp: Option<WallZone> = None;
            let area = close_holes(fp, |hole| {
                contains_own(hole, &inside, &islands)
                    || hole_width_below(hole, opts.min_hole)
                    || (!opts.hollow
                        && !walled_by(hole, wall_fp.get_or_insert_with(|| wall_zone(&walls))))
            });
            // Infill the perimeters do not enclose (a slicer setting without perimeters
            // somewhere) still holds up the layer above.
            let area = Located::new(area);
            let stray: Vec<&Path> = layer
                .paths
                .iter()
                .filter(|p| interior(p.role) && !path_inside(p, &area))
                .collect();
            let area = area.area;
            if stray.is_empty() {
                area
            } else {
                BooleanOps::union(&area, &footprint(stray))
            }
        }
        Outline::Infill => {
            let infill = midpoints(layer, |r| r == Role::Infill);
            close_holes(fp, |hole| {
                contains_any(hole, &infill) || hole_width_below(hole, opts.min_hole)
            })
        }
        Outline::Bare => close_holes(fp, |hole| hole_width_below(hole, opts.gap_close)),
    }
}

fn is_support(role: Role) -> bool {
    matches!(role, Role::Support | Role::SupportInterface)
}

/// The printed area of a layer with walls and support material: the part's (holes closed by
/// the walls' rule) and the support's (closed like a layer without roles: gaps between
/// support lines narrower than [`AreaOptions::gap_close`]), each on its own. Taken together,
/// a part standing in the support would close the support's gaps next to it into holes
/// holding the part's infill, and the layer would claim rows of air that the same support
/// alone (on a layer of its own height) leaves open.
fn with_support(layer: &Layer, opts: &AreaOptions) -> MultiPolygon<f64> {
    let part_area = printed_area(&without_support(layer), opts);
    let support_area = support_area(
        layer
            .paths
            .iter()
            .filter(|p| is_support(p.role))
            .map(|p| (&p.points[..], p.width)),
        opts,
    );
    BooleanOps::union(&part_area, &support_area)
}

/// The area support material strands (polyline, bead width) print: their footprint with
/// the gaps between lines narrower than [`AreaOptions::gap_close`] closed.
pub fn support_area<'a>(
    lines: impl IntoIterator<Item = (&'a [[f64; 2]], f64)>,
    opts: &AreaOptions,
) -> MultiPolygon<f64> {
    let support = Strands::of_lines(lines).buffer();
    close_holes(support, |hole| hole_width_below(hole, opts.gap_close))
}

/// `layer`'s strands but its support material's, in a layer of their own (no raw text).
fn without_support(layer: &Layer) -> Layer {
    Layer {
        paths: layer
            .paths
            .iter()
            .filter(|p| !is_support(p.role))
            .cloned()
            .collect(),
        raw: Vec::new(),
        start: None,
        objects: None,
        rests_on: Vec::new(),
        contact: Vec::new(),
        gap_below: Vec::new(),
        helical: false,
        ..*layer
    }
}

/// The area the part prints in a layer that prints support material beside it (`None` for
/// a layer without support, or of support alone, whose printed area is the part's as it
/// is): what a part's region is planned in. Support merged into the part's outline there
/// moved the part's perimeter along the support's edge, and its bead-round scallops cost a
/// hull's plan 40 ms an offset.
pub fn part_area(layer: &Layer, opts: &AreaOptions) -> Option<MultiPolygon<f64>> {
    let support = layer.paths.iter().filter(|p| is_support(p.role)).count();
    (support > 0 && support < layer.paths.len())
        .then(|| printed_area(&without_support(layer), opts))
}

/// Whether a path's first, middle and last points lie in `area`.
fn path_inside(p: &Path, area: &Located) -> bool {
    let n = p.points.len();
    if n == 0 {
        return true;
    }
    [p.points[0], p.points[n / 2], p.points[n - 1]]
        .iter()
        .all(|q| area.contains(q[0], q[1]))
}

/// A polygon set with its [`BoxIndex`](super::BoxIndex).
struct Located {
    area: MultiPolygon<f64>,
    index: super::BoxIndex,
}

impl Located {
    fn new(area: MultiPolygon<f64>) -> Self {
        let index = super::BoxIndex::new(&area);
        Located { area, index }
    }

    fn contains(&self, x: f64, y: f64) -> bool {
        self.index.contains(&self.area, x, y)
    }
}

/// Whether any of `points` (sorted by x) lies inside the ring.
fn contains_any(hole: &LineString<f64>, points: &[[f64; 2]]) -> bool {
    let Some(bb) = hole.bounding_rect() else {
        return false;
    };
    let from = points.partition_point(|p| p[0] < bb.min().x);
    let to = points.partition_point(|p| p[0] <= bb.max().x);
    let candidates = &points[from..to.max(from)];
    if !candidates
        .iter()
        .any(|p| p[1] >= bb.min().y && p[1] <= bb.max().y)
    {
        return false;
    }
    let poly = Polygon::new(hole.clone(), Vec::new());
    candidates
        .iter()
        .any(|p| p[1] >= bb.min().y && p[1] <= bb.max().y && poly.contains(&Point::new(p[0], p[1])))
}

/// [`contains_any`] leaving out the points inside an island that stands in the hole: the
/// hole round a post inside a ring (a torus on its post, a pin in a cup) is air, though the
/// post's infill lies within its edge.
fn contains_own(
    hole: &LineString<f64>,
    points: &[[f64; 2]],
    islands: &[(geo::Rect<f64>, Polygon<f64>)],
) -> bool {
    let Some(hb) = hole.bounding_rect() else {
        return false;
    };
    let within = |b: &geo::Rect<f64>| {
        b.min().x >= hb.min().x
            && b.max().x <= hb.max().x
            && b.min().y >= hb.min().y
            && b.max().y <= hb.max().y
    };
    let hole_poly = Polygon::new(hole.clone(), Vec::new());
    let nested: Vec<&Polygon<f64>> = islands
        .iter()
        .filter(|(b, q)| {
            within(b)
                && q.exterior()
                    .0
                    .first()
                    .is_some_and(|c| hole_poly.contains(&Point::new(c.x, c.y)))
        })
        .map(|(_, q)| q)
        .collect();
    if nested.is_empty() {
        return contains_any(hole, points);
    }
    let from = points.partition_point(|p| p[0] < hb.min().x);
    let to = points.partition_point(|p| p[0] <= hb.max().x);
    points[from..to.max(from)].iter().any(|p| {
        let q = Point::new(p[0], p[1]);
        p[1] >= hb.min().y
            && p[1] <= hb.max().y
            && hole_poly.contains(&q)
            && !nested.iter().any(|n| n.contains(&q))
    })
}

/// Where an external perimeter's inner edge can be: its footprint grown by a margin.
fn wall_zone(walls: &[&Path]) -> WallZone {
    WallZone::new(walls)
}

/// How far past a wall's bead a hole's edge point still runs along the wall (mm).
const WALL_ZONE: f64 = 0.1;

/// The external perimeters' segments on the proof's grid: whether a point lies within
/// [`WALL_ZONE`] of a wall's bead (its centreline within half its width, rounded to a
/// micrometre as the footprints are, plus that). The same points as the wall footprint grown
/// by [`WALL_ZONE`] holds, up to the arcs' chord tolerance (5 um), without buffering every
/// wall of the layer and growing the union (a twelfth of a plate of bowls' time).
struct WallZone {
    grid: super::proof::Grid,
    /// The widest wall's reach: every segment holding a point lies this near it.
    reach: f64,
}

impl WallZone {
    fn new(walls: &[&Path]) -> WallZone {
        let mut segs = Vec::new();
        let mut widest = 0.0f64;
        for p in walls {
            if p.points.len() < 2 || !(p.width > 0.0 && p.width < 50.0) {
                continue;
            }
            let half = (p.width * 1000.0).round() / 2000.0;
            widest = widest.max(half);
            for w in p.points.windows(2) {
                // A point that is no number would leave the grid empty.
                if w.iter().flatten().all(|v| v.is_finite()) {
                    segs.push(super::proof::Seg {
                        a: w[0],
                        b: w[1],
                        half,
                        role: p.role,
                        loop_at: None,
                    });
                }
            }
        }
        WallZone {
            grid: super::proof::Grid::new(segs),
            reach: widest + WALL_ZONE,
        }
    }

    fn contains(&self, x: f64, y: f64) -> bool {
        self.grid.any_near([x, y], self.reach, |s| {
            super::proof::dist2([x, y], s) <= (s.half + WALL_ZONE).powi(2)
        })
    }
}

/// Whether most of a hole's edge runs along an external perimeter.
fn walled_by(hole: &LineString<f64>, walls: &WallZone) -> bool {
    let n = hole.0.len().saturating_sub(1).max(1);
    let on_wall = hole.0[..n]
        .iter()
        .filter(|c| walls.contains(c.x, c.y))
        .count();
    on_wall * 2 >= n
}

/// Whether no disc of diameter `width` fits in the hole.
fn hole_width_below(hole: &LineString<f64>, width: f64) -> bool {
    // Cheap verdicts first: a disc fits in neither a box narrower than it nor an area smaller
    // than its own.
    if let Some(bb) = hole.bounding_rect() {
        if bb.width().min(bb.height()) < width {
            return true;
        }
    }
    let ring = Polygon::new(hole.clone(), Vec::new());
    if ring.unsigned_area() < std::f64::consts::FRAC_PI_4 * width * width {
        return true;
    }
    // A point inside at least a hundredth of a millimetre more than the disc's radius from
    // the edge: the shrunk hole keeps a disc round it (area above 3e-4 mm2), so the verdict
    // is the offset's without it (a bowl's inside, every layer).
    if let Some(c) = geo::Centroid::centroid(&ring) {
        use geo::{Contains, Distance, Euclidean};
        if ring.contains(&c) && Euclidean.distance(&c, hole) >= width / 2.0 + 0.01 {
            return false;
        }
    }
    let poly = MultiPolygon::new(vec![ring]);
    offset(&poly, -width / 2.0).unsigned_area() < 1e-6
}

/// Fills the holes for which `close` says so. A filled hole becomes material except where
/// other islands of the footprint sit inside it: those keep their own holes, which get their
/// own verdict.
fn close_holes(
    fp: MultiPolygon<f64>,
    mut close: impl FnMut(&LineString<f64>) -> bool,
) -> MultiPolygon<f64> {
    // Each polygon's bounding box and first exterior point, to find islands in a hole.
    type Outline = (Option<geo::Rect<f64>>, Option<geo::Coord<f64>>);
    let exteriors: Vec<Outline> =
        fp.0.iter()
            .map(|q| (q.bounding_rect(), q.exterior().0.first().copied()))
            .collect();
    let mut kept: Vec<Polygon<f64>> = Vec::with_capacity(fp.0.len());
    // Filled holes with islands inside them: only these need a boolean union.
    let mut fills: Vec<Polygon<f64>> = Vec::new();
    for (pi, p) in fp.0.into_iter().enumerate() {
        let (exterior, interiors) = p.into_inner();
        let mut open = Vec::with_capacity(interiors.len());
        for hole in interiors {
            if !close(&hole) {
                open.push(hole);
                continue;
            }
            let Some(hb) = hole.bounding_rect() else {
                continue;
            };
            // Islands whose box lies in the hole's box and whose first point lies in the hole.
            let hp = Polygon::new(hole.clone(), Vec::new()).orient(Direction::Default);
            let nested: Vec<usize> = exteriors
                .iter()
                .enumerate()
                .filter(|(qi, (qb, first))| {
                    *qi != pi
                        && qb.is_some_and(|b| {
                            b.min().x >= hb.min().x
                                && b.max().x <= hb.max().x
                                && b.min().y >= hb.min().y
                                && b.max().y <= hb.max().y
                        })
                        && first.is_some_and(|c| hp.contains(&Point::from(c)))
                })
                .map(|(qi, _)| qi)
                .collect();
            if !nested.is_empty() {
                // The hole stays in its polygon; the fill around the islands is added below.
                open.push(hole);
                fills.push(hp);
            }
        }
        kept.push(Polygon::new(exterior, open));
    }
    if fills.is_empty() {
        return MultiPolygon::new(kept);
    }
    // A filled hole covers the islands in it, but not their own open holes: fill the hole
    // minus the islands' outlines, then union with everything.
    let islands: Vec<Polygon<f64>> = kept.iter().map(super::exterior_only).collect();
    let mut parts: Vec<Polygon<f64>> = Vec::new();
    for hp in fills {
        let inner: Vec<&Polygon<f64>> = islands
            .iter()
            .filter(|q| {
                q.exterior()
                    .0
                    .first()
                    .is_some_and(|c| hp.contains(&Point::from(*c)))
            })
            .collect();
        parts.extend(BooleanOps::difference(&hp, &unary_union(inner)).0);
    }
    unary_union(kept.iter().chain(parts.iter()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::layers::Role;

    use crate::layers::testing::path;

    #[test]
    fn a_raster_s_enclosed_runs_are_the_cells_a_flood_from_its_edge_does_not_reach() {
        // Random rasters (widths across word boundaries, densities from sparse to solid)
        // against a cell-by-cell flood from the edge.
        let mut rand = crate::layers::testing::xorshift(0x9e37_79b9_7f4a_7c15);
        for case in 0..300 {
            let nx = 1 + (rand() % 150) as usize;
            let ny = 1 + (rand() % 40) as usize;
            let density = (case % 10) as u64;
            let stride = nx.div_ceil(64);
            let mut bits = vec![0u64; stride * ny];
            let mut set = vec![false; nx * ny];
            for r in 0..ny {
                for c in 0..nx {
                    if rand() % 10 < density {
                        set[r * nx + c] = true;
                        bits[r * stride + c / 64] |= 1 << (c % 64);
                    }
                }
            }
            let mut out = vec![false; nx * ny];
            let mut stack: Vec<(usize, usize)> = (0..ny)
                .flat_map(|r| [(r, 0), (r, nx - 1)])
                .chain((0..nx).flat_map(|c| [(0, c), (ny - 1, c)]))
                .collect();
            while let Some((r, c)) = stack.pop() {
                let k = r * nx + c;
                if set[k] || out[k] {
                    continue;
                }
                out[k] = true;
                if r > 0 {
                    stack.push((r - 1, c));
                }
                if r + 1 < ny {
                    stack.push((r + 1, c));
                }
                if c > 0 {
                    stack.push((r, c - 1));
                }
                if c + 1 < nx {
                    stack.push((r, c + 1));
                }
            }
            let runs = enclosed_runs(&bits, nx, ny, stride);
            for r in 0..ny {
                let mut kept = vec![false; nx];
                for &(_, a, b) in &runs.runs[runs.row(r)] {
                    assert!(a < b && b <= nx);
                    kept[a..b].iter_mut().for_each(|k| *k = true);
                }
                let want: Vec<bool> = (0..nx).map(|c| !out[r * nx + c]).collect();
                assert_eq!(kept, want, "case {case} row {r} ({nx} x {ny})");
            }
            // Their outline covers those cells and no others: as much area, and every
            // cell's centre inside it exactly when the cell is kept.
            let outline = runs_outline(&runs, |c| c as f64, |r| r as f64);
            let cells = out.iter().filter(|o| !**o).count() as f64;
            assert!(
                (outline.unsigned_area() - cells).abs() < 1e-6,
                "case {case}: {} vs {cells}",
                outline.unsigned_area()
            );
            for r in 0..ny {
                for c in 0..nx {
                    let centre = Point::new(c as f64 + 0.5, r as f64 + 0.5);
                    assert_eq!(
                        geo::Contains::contains(&outline, &centre),
                        !out[r * nx + c],
                        "case {case}: cell {r} {c}"
                    );
                }
            }
        }
    }

    #[test]
    fn a_pile_of_strokes_is_drawn_on_a_raster_true_to_a_cell_and_without_specks_of_holes() {
        // A damaged layer: 300 strokes back and forth over one 10 mm line, and a square
        // ring scribbled over 40 times. Crowded, so rasterised: the line's footprint is its
        // capsule, to a cell; the ring's inside, enclosed by the pile, is filled.
        let mut line = Vec::new();
        for i in 0..300 {
            line.push(if i % 2 == 0 { [0.0, 0.0] } else { [10.0, 0.0] });
        }
        let s = Strands::of_lines([(&line[..], 0.45)]);
        assert!(s.crowded());
        let f = s.buffer();
        let capsule = 10.0 * 0.45 + std::f64::consts::PI * 0.225 * 0.225;
        assert!(
            (f.unsigned_area() - capsule).abs() < 0.06 * capsule,
            "{} vs {capsule}",
            f.unsigned_area()
        );
        assert_eq!(f.0.len(), 1);
        // The scribbled ring: one outline, its inside filled (a pile's holes are specks
        // the slicer never meant).
        let mut ring = Vec::new();
        for _ in 0..40 {
            ring.extend([[0.0, 0.0], [6.0, 0.0], [6.0, 6.0], [0.0, 6.0]]);
        }
        ring.push([0.0, 0.0]);
        let s = Strands::of_lines([(&ring[..], 0.45)]);
        assert!(s.crowded());
        let f = s.buffer();
        assert_eq!(f.0.len(), 1);
        assert!(f.0[0].interiors().is_empty());
        let square = 6.45 * 6.45;
        assert!(
            (f.unsigned_area() - square).abs() < 0.03 * square,
            "{} vs {square}",
            f.unsigned_area()
        );
        // A pile stays crowded when a move far away and back thins the layer's mean out
        // (a damaged digit: X 97104 for X 97.104): the exact buffer of the pile took 18 GB.
        let mut far = ring.clone();
        far.extend([[97_104.0, 0.0], [0.0, 0.0]]);
        assert!(Strands::of_lines([(&far[..], 0.45)]).crowded());
        // A slicer's solid layer is not crowded.
        let solid: Vec<[f64; 2]> = (0..100)
            .flat_map(|i| {
                let y = 0.45 * i as f64;
                if i % 2 == 0 {
                    [[0.0, y], [40.0, y]]
                } else {
                    [[40.0, y], [0.0, y]]
                }
            })
            .collect();
        assert!(!Strands::of_lines([(&solid[..], 0.45)]).crowded());
        // Where a row meets a stroke's capsule.
        let (l, r) = capsule_row([0.0, 0.0], [10.0, 0.0], 0.5, 0.3).unwrap();
        assert!((l + 0.4).abs() < 1e-9 && (r - 10.4).abs() < 1e-9, "{l} {r}");
        assert!(capsule_row([0.0, 0.0], [10.0, 0.0], 0.5, 0.6).is_none());
    }

    #[test]
    fn a_finely_divided_strand_has_the_footprint_of_its_chords() {
        // A 5 mm circle in 4000 segments (7.9 um each) at width 0.45: its footprint is the
        // annulus (area 2 pi r w), buffered from a few hundred chords within a micrometre.
        let circle = |n: usize| -> Vec<[f64; 2]> {
            (0..=n)
                .map(|i| {
                    let a = std::f64::consts::TAU * i as f64 / n as f64;
                    [5.0 * a.cos(), 5.0 * a.sin()]
                })
                .collect()
        };
        let ring = circle(4000);
        let s = Strands::of_lines([(&ring[..], 0.45)]);
        let kept: usize = s.0.values().flatten().map(|l| l.0.len()).sum();
        assert!(kept < 400, "{kept} points kept");
        let f = s.buffer();
        let annulus = std::f64::consts::TAU * 5.0 * 0.45;
        assert!(
            (f.unsigned_area() - annulus).abs() < 0.005 * annulus,
            "{} vs {annulus}",
            f.unsigned_area()
        );
        // Every point of the ring lies within a micrometre of the chords buffered.
        let chords = &s.0.values().next().unwrap()[0];
        for q in ring.iter().step_by(37) {
            let d = chords
                .0
                .windows(2)
                .map(|w| {
                    crate::geometry::nearest_on_segment(*q, [w[0].x, w[0].y], [w[1].x, w[1].y]).1
                })
                .map(|n| (n[0] - q[0]).hypot(n[1] - q[1]))
                .fold(f64::INFINITY, f64::min);
            assert!(
                d <= DENSE_SIMPLIFY + 1e-9,
                "{q:?} is {d} mm from the chords"
            );
        }
        // A slicer's polyline (segments of a few tenths) is kept as written.
        let coarse = circle(100);
        let s = Strands::of_lines([(&coarse[..], 0.45)]);
        assert_eq!(
            s.0.values().flatten().map(|l| l.0.len()).sum::<usize>(),
            101
        );
    }

    #[test]
    fn a_disc_fits_in_a_hole_exactly_when_the_shrunk_hole_is_left() {
        // Rings, rectangles, an L and a thin slot, for discs of several sizes: the quick
        // verdict (a point far enough inside) agrees with shrinking the hole.
        let circle = |r: f64| -> LineString<f64> {
            (0..=64)
                .map(|i| {
                    let a = std::f64::consts::TAU * i as f64 / 64.0;
                    (r * a.cos(), r * a.sin())
                })
                .collect::<Vec<_>>()
                .into()
        };
        let holes: Vec<LineString<f64>> = vec![
            circle(0.2),
            circle(0.26),
            circle(5.0),
            square(0.0, 0.0, 0.5)
                .iter()
                .map(|p| (p[0], p[1]))
                .collect::<Vec<_>>()
                .into(),
            vec![(0.0, 0.0), (4.0, 0.0), (4.0, 0.3), (0.0, 0.3), (0.0, 0.0)].into(),
            vec![
                (0.0, 0.0),
                (6.0, 0.0),
                (6.0, 1.0),
                (1.0, 1.0),
                (1.0, 6.0),
                (0.0, 6.0),
                (0.0, 0.0),
            ]
            .into(),
        ];
        for hole in &holes {
            for width in [0.1, 0.3, 0.45, 0.5, 0.9, 2.0] {
                let poly = MultiPolygon::new(vec![Polygon::new(hole.clone(), Vec::new())]);
                let slow = offset(&poly, -width / 2.0).unsigned_area() < 1e-6;
                assert_eq!(hole_width_below(hole, width), slow, "{hole:?} {width}");
            }
        }
    }

    #[test]
    fn the_wall_zone_holds_what_the_grown_wall_footprint_holds() {
        // A ring of 0.45 mm walls, a square of 0.42 mm ones and a long diagonal: points on a
        // 0.05 mm grid, answered alike away from the zone's edge (the footprint's arcs are
        // chords within 5 um of it).
        let ring: Vec<[f64; 2]> = (0..=96)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / 96.0;
                [10.0 + 6.0 * a.cos(), 10.0 + 6.0 * a.sin()]
            })
            .collect();
        let walls = [
            path(Role::ExternalPerimeter, 0.45, &ring),
            path(Role::ExternalPerimeter, 0.42, &square(1.0, 1.0, 5.0)),
            path(Role::ExternalPerimeter, 0.45, &[[0.0, 20.0], [20.0, 0.3]]),
        ];
        let refs: Vec<&Path> = walls.iter().collect();
        let grown = Located::new(offset(&footprint(refs.iter().copied()), WALL_ZONE));
        let zone = WallZone::new(&refs);
        let mut checked = 0;
        for i in 0..440 {
            for j in 0..440 {
                let (x, y) = (i as f64 * 0.05 - 1.0, j as f64 * 0.05 - 1.0);
                let margin = walls
                    .iter()
                    .flat_map(|p| {
                        let half = p.width / 2.0;
                        p.points.windows(2).map(move |w| {
                            let (_, q) = crate::geometry::nearest_on_segment([x, y], w[0], w[1]);
                            (q[0] - x).hypot(q[1] - y) - half - WALL_ZONE
                        })
                    })
                    .fold(f64::INFINITY, f64::min);
                if margin.abs() < 0.01 {
                    continue;
                }
                checked += 1;
                assert_eq!(zone.contains(x, y), grown.contains(x, y), "({x}, {y})");
            }
        }
        assert!(checked > 150_000, "{checked}");
    }

    fn square(x: f64, y: f64, side: f64) -> Vec<[f64; 2]> {
        vec![
            [x, y],
            [x + side, y],
            [x + side, y + side],
            [x, y + side],
            [x, y],
        ]
    }

    #[test]
    fn parts_apart_are_buffered_alone_and_give_the_same_footprint() {
        let w = 0.45;
        // Two squares 3 mm apart, and a third whose bead touches the second's (0.3 mm gap).
        let paths = vec![
            path(Role::ExternalPerimeter, w, &square(0.0, 0.0, 10.0)),
            path(Role::ExternalPerimeter, w, &square(13.0, 0.0, 10.0)),
            path(Role::Perimeter, 0.5, &square(23.3, 0.0, 5.0)),
        ];
        let strands = Strands::of(&paths);
        let groups = strands.split().expect("two groups");
        assert_eq!(groups.len(), 2);
        let sizes: Vec<usize> = groups
            .iter()
            .map(|g| g.0.values().map(Vec::len).sum())
            .collect();
        assert_eq!(sizes, vec![1, 2], "the touching squares stay together");
        let split = strands.buffer();
        let whole = strands.buffer_whole();
        assert_eq!(split.0.len(), whole.0.len());
        let (a, b) = (split.unsigned_area(), whole.unsigned_area());
        assert!((a - b).abs() < 1e-3 * b, "{a} vs {b}");
        // One part: no split.
        assert!(Strands::of(&paths[..1]).split().is_none());
    }

    /// A loop of `n` points round `c` of radius `r`, counter-clockwise from angle 0, closed.
    fn ring(c: [f64; 2], r: f64, n: usize) -> Vec<[f64; 2]> {
        (0..=n)
            .map(|k| {
                let a = std::f64::consts::TAU * k as f64 / n as f64;
                [c[0] + r * a.cos(), c[1] + r * a.sin()]
            })
            .collect()
    }

    #[test]
    fn walls_are_not_joined_across_the_hole_they_wind_round() {
        let w = 0.45;
        let c = [10.0, 10.0];
        let outline = [
            [0.0, 0.0],
            [20.0, 0.0],
            [20.0, 20.0],
            [0.0, 20.0],
            [0.0, 0.0],
        ];
        let hole_wall = path(Role::ExternalPerimeter, w, &ring(c, 0.9, 16));
        // The perimeter round the hole, printed next, starts 2.2 mm from the wall's end (at
        // 10.9, 10), across the hole.
        let mut round: Vec<[f64; 2]> = ring(c, 1.33, 16);
        round.rotate_left(8);
        round.pop();
        round.push(round[0]);
        let round = path(Role::Perimeter, w, &round);
        // Two short pieces of a threading perimeter, turned back on each other, 2 mm apart
        // across the hole.
        let a = path(Role::Perimeter, w, &[[8.6, 9.0], [8.6, 9.2]]);
        let b = path(Role::Perimeter, w, &[[10.6, 9.0], [10.4, 9.0]]);
        // A perimeter split where its width changes: a run of two pieces closing a loop
        // round the hole, the first one's own ends 2.1 mm apart on either side of it (and
        // within a fifth of its length).
        let first = path(
            Role::Perimeter,
            w,
            &[[8.95, 10.0], [8.95, 5.0], [11.05, 5.0], [11.05, 10.0]],
        );
        let second = path(
            Role::Perimeter,
            w * 1.1,
            &[[11.05, 10.0], [11.05, 14.0], [8.95, 14.0], [8.95, 10.0]],
        );
        let l = layer(vec![
            path(Role::ExternalPerimeter, w, &outline),
            hole_wall,
            round,
            a,
            b,
            first,
            second,
        ]);
        let joins = wall_joins(&l);
        for j in &joins {
            let (p, q) = (j.points[0], j.points[1]);
            let mid = [(p[0] + q[0]) / 2.0, (p[1] + q[1]) / 2.0];
            let d = ((mid[0] - c[0]).powi(2) + (mid[1] - c[1]).powi(2)).sqrt();
            assert!(d > 1.3, "a join across the hole: {p:?} -> {q:?}");
        }
        // The hole stays open for the layer above.
        let area = printed_area(&l, &AreaOptions::default());
        assert!(!area.contains(&geo::Point::new(c[0], c[1])));
        assert!(area.0.iter().any(|p| !p.interiors().is_empty()));
    }

    #[test]
    fn a_wall_open_by_a_coasted_gap_still_outlines_the_part() {
        // Cura coasts over the last 1.9 mm of a bridged wall: the loop is open there, and
        // the bridge skin inside would otherwise be strays with gaps between them.
        let w = 0.4;
        let mut paths = vec![
            path(
                Role::ExternalPerimeter,
                w,
                &[[0.0, 20.0], [0.0, 0.0], [8.1, 0.0]],
            ),
            path(
                Role::OverhangPerimeter,
                w,
                &[[10.0, 0.0], [50.0, 0.0], [50.0, 20.0], [10.0, 20.0]],
            ),
            path(Role::ExternalPerimeter, w, &[[10.0, 20.0], [0.0, 20.0]]),
        ];
        for i in 1..49 {
            let x = i as f64 * 1.0;
            paths.push(path(Role::BridgeInfill, w, &[[x, 0.4], [x, 19.6]]));
        }
        let a = printed_area(&layer(paths), &AreaOptions::default());
        assert!(
            (a.unsigned_area() - 50.4 * 20.4).abs() < 5.0,
            "{}",
            a.unsigned_area()
        );
        assert!(a.0.iter().all(|p| p.interiors().is_empty()));
    }

    #[test]
    fn a_rewritten_layer_s_walls_meeting_end_to_end_outline_it_whatever_their_order() {
        // poa's moved perimeter meets the slicer's perimeter it kept 0.6 mm apart at both
        // ends (a slit of 0.15 mm between the beads); solid infill fills the inside. Printed
        // one after the other, the pieces were joined at one end only: the slit at the other
        // opened the inside to the air, its infill became strays with gaps between them.
        let w = 0.45;
        let kept = || {
            path(
                Role::ExternalPerimeter,
                w,
                &[[0.0, 0.6], [0.0, 20.0], [30.0, 20.0]],
            )
        };
        let moved = || {
            path(
                Role::OverhangPerimeter,
                w,
                &[[30.6, 20.0], [30.6, 19.4], [30.6, 0.0], [0.0, 0.0]],
            )
        };
        let infill = || -> Vec<Path> {
            (1..30)
                .map(|i| {
                    let x = i as f64;
                    path(Role::SolidInfill, w, &[[x, 0.45], [x, 19.55]])
                })
                .collect()
        };
        let whole = 30.6 * 20.0;
        for order in 0..3 {
            let mut paths = match order {
                0 => vec![kept(), moved()],
                1 => vec![moved(), kept()],
                _ => vec![kept()],
            };
            paths.extend(infill());
            if order == 2 {
                paths.push(moved());
            }
            let l = layer(paths);
            // As the slicer printed them, the walls are joined only end to end in print order.
            let sliced = printed_area(&l, &AreaOptions::default());
            assert!(sliced.unsigned_area() < whole - 100.0, "order {order}");
            let a = printed_area_any_order(&l, &AreaOptions::default());
            assert!(
                a.unsigned_area() > whole && a.0.iter().all(|p| p.interiors().is_empty()),
                "order {order}: {} mm2, holes {}",
                a.unsigned_area(),
                a.0.iter().map(|p| p.interiors().len()).sum::<usize>()
            );
        }
        // Ends farther apart than a width and a half are not taken as one wall.
        let l = layer(vec![
            path(Role::ExternalPerimeter, w, &[[0.0, 0.0], [10.0, 0.0]]),
            path(Role::SolidInfill, w, &[[0.0, 5.0], [10.0, 5.0]]),
            path(Role::ExternalPerimeter, w, &[[10.7, 0.0], [20.0, 0.0]]),
        ]);
        let mut joins = Vec::new();
        end_joins(&l, &mut joins);
        assert!(joins.is_empty(), "{joins:?}");
        let l = layer(vec![
            path(Role::ExternalPerimeter, w, &[[0.0, 0.0], [10.0, 0.0]]),
            path(Role::SolidInfill, w, &[[0.0, 5.0], [10.0, 5.0]]),
            path(Role::ExternalPerimeter, w, &[[10.6, 0.0], [20.0, 0.0]]),
        ]);
        end_joins(&l, &mut joins);
        assert_eq!(joins.len(), 1, "{joins:?}");
        assert_eq!(joins[0].points, vec![[10.0, 0.0], [10.6, 0.0]]);
    }

    fn layer(paths: Vec<Path>) -> Layer {
        crate::layers::testing::layer(1, paths)
    }

    fn square_loop(role: Role, x0: f64, y0: f64, x1: f64, y1: f64) -> Path {
        path(
            role,
            0.45,
            &[[x0, y0], [x1, y0], [x1, y1], [x0, y1], [x0, y0]],
        )
    }

    #[test]
    fn a_part_s_area_leaves_out_the_support_printed_beside_it() {
        // A 10 x 10 walled square with infill and support lines 0.2 mm off its right side: the layer's
        // printed area joins them; the part's is the square alone, and a layer of walls or
        // of support alone has no part area of its own.
        let part = square_loop(Role::ExternalPerimeter, 0.225, 0.225, 9.775, 9.775);
        let support: Vec<Path> = (0..8)
            .map(|i| {
                let y = 0.5 + 1.2 * i as f64;
                path(Role::Support, 0.4, &[[10.2, y], [14.0, y]])
            })
            .collect();
        let opts = AreaOptions::default();
        let infill = path(Role::Infill, 0.45, &[[1.0, 1.0], [9.0, 9.0]]);
        let mut paths = vec![part.clone(), infill];
        paths.extend(support.iter().cloned());
        let l = layer(paths);
        let whole = printed_area(&l, &opts);
        let own = part_area(&l, &opts).expect("a layer of part and support");
        assert!(whole.unsigned_area() > 110.0, "{}", whole.unsigned_area());
        assert!(
            (own.unsigned_area() - 100.0).abs() < 0.5,
            "{}",
            own.unsigned_area()
        );
        use geo::BoundingRect;
        let b = own.bounding_rect().unwrap();
        assert!(b.max().x < 10.01 && b.min().x > -0.01, "{b:?}");
        assert!(part_area(&layer(vec![part]), &opts).is_none());
        assert!(part_area(&layer(support), &opts).is_none());
    }

    #[test]
    fn horizontal_single_segment_strands_keep_their_area() {
        // Ten horizontal two-point strands 0.45 wide, 0.45 apart: a solid 10 x 4.5 patch.
        let paths: Vec<Path> = (0..10)
            .map(|i| {
                let y = 0.225 + 0.45 * i as f64;
                path(Role::Unknown, 0.45, &[[0.0, y], [10.0, y]])
            })
            .collect();
        let fp = footprint(&paths);
        // Rounded caps add pi r^2 per strand end pair, minus overlaps: between 45 and 46.6.
        let a = fp.unsigned_area();
        assert!(a > 45.0 && a < 46.7, "{a}");
        let area = printed_area(&layer(paths), &AreaOptions::default());
        assert!((area.unsigned_area() - a).abs() < 1e-6);
    }

    #[test]
    fn overhang_perimeters_outline_a_layer_with_no_external_perimeter() {
        // A floating plate's first layer as PrusaSlicer writes it: every wall an overhang
        // perimeter (a 20 x 20 outline and a 4 x 4 hole), bridge infill between them. The
        // walls outline it (no strand-by-strand buffering of the infill) and the hole stays a
        // hole.
        let mut paths = vec![
            square_loop(Role::OverhangPerimeter, 0.225, 0.225, 19.775, 19.775),
            square_loop(Role::OverhangPerimeter, 7.775, 7.775, 12.225, 12.225),
        ];
        for i in 0..43 {
            let y = 0.675 + 0.45 * i as f64;
            if y > 7.5 && y < 12.5 {
                paths.push(path(Role::BridgeInfill, 0.45, &[[0.45, y], [7.55, y]]));
                paths.push(path(Role::BridgeInfill, 0.45, &[[12.45, y], [19.55, y]]));
            } else {
                paths.push(path(Role::BridgeInfill, 0.45, &[[0.45, y], [19.55, y]]));
            }
        }
        let l = layer(paths);
        assert_eq!(outline(&l), Outline::Walls);
        let area = printed_area(&l, &AreaOptions::default());
        assert!(
            (area.unsigned_area() - 384.0).abs() < 0.5,
            "{}",
            area.unsigned_area()
        );
        assert_eq!(area.0.len(), 1);
        assert_eq!(area.0[0].interiors().len(), 1);
    }

    #[test]
    fn sparse_infill_gaps_are_not_air() {
        // A 20 x 20 wall loop with two perimeters and sparse infill lines 3 mm apart.
        let mut paths = vec![
            square_loop(Role::ExternalPerimeter, 0.225, 0.225, 19.775, 19.775),
            square_loop(Role::Perimeter, 0.65, 0.65, 19.35, 19.35),
        ];
        for i in 0..6 {
            let x = 2.0 + 3.0 * i as f64;
            paths.push(path(Role::Infill, 0.45, &[[x, 0.8], [x, 19.2]]));
        }
        let area = printed_area(&layer(paths.clone()), &AreaOptions::default());
        assert!(
            (area.unsigned_area() - 400.0).abs() < 0.5,
            "{}",
            area.unsigned_area()
        );
        assert!(area.0.iter().all(|p| p.interiors().is_empty()));
        // The same without roles: closed by width.
        for p in &mut paths {
            p.role = Role::Unknown;
        }
        let area = printed_area(&layer(paths), &AreaOptions::default());
        assert!(
            (area.unsigned_area() - 400.0).abs() < 0.5,
            "{}",
            area.unsigned_area()
        );
    }

    #[test]
    fn a_hollow_part_is_open_inside() {
        // Two perimeters round nothing (`fill_density = 0%`): the inside, walled by the
        // inner perimeter, is a gap an infill rule cannot see into unless the part is hollow.
        let paths = vec![
            square_loop(Role::ExternalPerimeter, 0.225, 0.225, 19.775, 19.775),
            square_loop(Role::Perimeter, 0.65, 0.65, 19.35, 19.35),
        ];
        let closed = printed_area(&layer(paths.clone()), &AreaOptions::default());
        assert!((closed.unsigned_area() - 400.0).abs() < 0.5);
        let hollow = AreaOptions {
            hollow: true,
            ..Default::default()
        };
        let open = printed_area(&layer(paths.clone()), &hollow);
        // The ring of the two beads: 20 x 20 less the 18.25 mm square inside the inner one.
        let ring = 400.0 - 18.25 * 18.25;
        assert!(
            (open.unsigned_area() - ring).abs() < 0.5,
            "{}",
            open.unsigned_area()
        );
        // Infill in it: closed all the same.
        let mut filled = paths.clone();
        filled.push(path(Role::Infill, 0.45, &[[2.0, 0.8], [2.0, 19.2]]));
        assert!((printed_area(&layer(filled), &hollow).unsigned_area() - 400.0).abs() < 0.5);
        // A strip of solid infill along one wall holds itself only: the inside stays open
        // but for the strip's footprint (0.85 mm past the inner wall, 18.25 long).
        let mut strip = paths;
        for x in [1.1, 1.5] {
            strip.push(path(Role::SolidInfill, 0.45, &[[x, 0.875], [x, 19.125]]));
        }
        let a = printed_area(&layer(strip), &hollow).unsigned_area();
        let want = ring + 0.85 * 18.25;
        assert!((a - want).abs() < 0.3, "{a} vs {want}");
    }

    #[test]
    fn real_holes_stay_open() {
        // A 30 x 30 part with a 10 x 10 hole, each walled by an external perimeter.
        let paths = vec![
            square_loop(Role::ExternalPerimeter, 0.225, 0.225, 29.775, 29.775),
            square_loop(Role::ExternalPerimeter, 9.775, 9.775, 20.225, 20.225),
            square_loop(Role::Perimeter, 0.65, 0.65, 29.35, 29.35),
            square_loop(Role::Perimeter, 9.35, 9.35, 20.65, 20.65),
            path(Role::Infill, 0.45, &[[1.0, 1.0], [8.0, 8.0]]),
        ];
        let area = printed_area(&layer(paths.clone()), &AreaOptions::default());
        let a = area.unsigned_area();
        assert!((a - 800.0).abs() < 1.0, "{a}");
        // An island inside the real hole keeps its place, and the hole stays open around it.
        let mut with_island = paths;
        with_island.push(square_loop(Role::ExternalPerimeter, 14.5, 14.5, 15.5, 15.5));
        let area = printed_area(&layer(with_island), &AreaOptions::default());
        let b = area.unsigned_area();
        // 1.45 mm square with corners rounded by 0.225 mm; its 0.55 mm eye is closed.
        let island = 1.45 * 1.45 - (4.0 - std::f64::consts::PI) * 0.225 * 0.225;
        assert!((b - a - island).abs() < 0.05, "{b}");
    }

    #[test]
    fn the_hole_round_a_post_with_infill_stays_open() {
        // A ring (a torus' first layers) round a post of its own, the post filled with
        // infill: the post's infill lies in the ring's hole but says nothing about it (it
        // was closed, and loops grew across the gap from the post).
        let mut paths = vec![
            square_loop(Role::ExternalPerimeter, 0.225, 0.225, 29.775, 29.775),
            square_loop(Role::ExternalPerimeter, 4.775, 4.775, 25.225, 25.225),
            square_loop(Role::Perimeter, 0.65, 0.65, 29.35, 29.35),
            square_loop(Role::Perimeter, 4.35, 4.35, 25.65, 25.65),
            path(Role::Infill, 0.45, &[[1.0, 1.0], [3.9, 3.9]]),
            // The post: 10 x 10 in the middle, two walls and infill.
            square_loop(Role::ExternalPerimeter, 10.225, 10.225, 19.775, 19.775),
            square_loop(Role::Perimeter, 10.65, 10.65, 19.35, 19.35),
        ];
        let ring = printed_area(&layer(paths.clone()), &AreaOptions::default()).unsigned_area();
        paths.push(path(Role::Infill, 0.45, &[[11.0, 11.0], [19.0, 19.0]]));
        paths.push(path(Role::Infill, 0.45, &[[11.0, 19.0], [19.0, 11.0]]));
        let with_infill = printed_area(&layer(paths), &AreaOptions::default()).unsigned_area();
        // Ring 900 - 400 = 500 mm2, post 100 mm2: the gap between them (300 mm2) stays open.
        assert!((ring - 600.0).abs() < 1.5, "{ring}");
        assert!((with_infill - ring).abs() < 1.5, "{with_infill} vs {ring}");
    }
}
