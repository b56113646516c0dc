//! Stage 4: what each layer covers and what would be printed over air.
//!
//! Input: [`Layer`]s from [`crate::layers`]. Output: each layer's printed area (a
//! `MultiPolygon` in mm) and the [`Region`]s of a layer that lie farther than a tolerance from
//! the area printed below it, classified as overhang or bridge.
//!
//! Invariants: this is the only module that talks to Clipper (through geo-clipper), and it owns
//! the coordinate scaling that needs ([`CLIPPER_SCALE`]). Strand footprints and booleans use
//! geo (whose `Buffer` keeps horizontal two-point strands that Clipper's offset drops);
//! polygon offsets use Clipper, which stays linear in vertex count. Areas are in mm2, lengths in
//! mm.

pub mod area;
pub mod coverage;
pub mod detect;
pub mod proof;
pub mod regions;
pub mod ring_index;

pub use area::{
    footprint, footprint_if_spread, printed_area, printed_area_any_order, rewritten_area,
    AreaOptions,
};
pub use detect::{detect, read_ahead, Detected};
pub use regions::{
    find_regions, find_regions_as_sliced, DetectOptions, Region, RegionKind, RoleExtrusion,
    Tolerance,
};
pub use ring_index::RingIndex;

use geo::{MultiPolygon, Polygon};
use geo_clipper::{Clipper, EndType, JoinType};

/// The empty area (nothing printed).
pub static NO_AREA: MultiPolygon<f64> = MultiPolygon(Vec::new());

/// Clipper works on integers: coordinates are multiplied by this (0.1 um resolution).
pub const CLIPPER_SCALE: f64 = 10_000.0;
/// Largest distance (mm) between a round offset's arc and its chords.
pub const ARC_TOLERANCE: f64 = 0.005;

/// Keeps the polygon library's own panics off stderr: the planner and the region search catch
/// them (the region, or the layer, is left as sliced), so the message and backtrace would
/// only alarm.
/// Every other panic is printed as before. For binaries; a library leaves the hook alone.
pub fn quiet_polygon_panics() {
    let before = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        if info
            .location()
            .is_some_and(|l| l.file().contains("i_overlay"))
        {
            return;
        }
        before(info)
    }));
}

/// Grows (`delta` > 0) or shrinks a polygon set by `delta` mm with round joins.
pub fn offset(mp: &MultiPolygon<f64>, delta: f64) -> MultiPolygon<f64> {
    if mp.0.is_empty() {
        return MultiPolygon::new(Vec::new());
    }
    let pruned = (delta > 0.0)
        .then(|| without_closing_holes(mp, delta))
        .flatten();
    let src = pruned.as_ref().unwrap_or(mp);
    if delta > 0.0 && src.0.len() == 1 && src.0[0].interiors().len() > MANY_HOLES {
        if let Some(grown) = grow_holed(&src.0[0], delta) {
            return grown;
        }
    }
    clipper_offset(src, delta)
}

fn clipper_offset(mp: &MultiPolygon<f64>, delta: f64) -> MultiPolygon<f64> {
    mp.offset(
        delta,
        JoinType::Round(ARC_TOLERANCE * CLIPPER_SCALE),
        EndType::ClosedPolygon,
        CLIPPER_SCALE,
    )
}

/// Holes above which a polygon is grown by [`grow_holed`].
const MANY_HOLES: usize = 32;

/// A polygon with many holes (a perforated plate's layer, 900 of them) grown by `delta > 0`
/// without offsetting its holes together: Clipper resolves all the rings in one sweep whose
/// intersection pass is quadratic in the rings a scanline meets (a row of 30 holes: 0.5 s a
/// growth). The holes are apart from each other and from the outside, so a disc lies in
/// the part's complement only inside one of them: growing the part is growing its outline
/// alone and shrinking each hole on its own, the shrunk holes lying inside the grown outline
/// (they lie inside the outline; a hole its growth closes lies outside it). `None` when
/// the grown outline is not one polygon (the general path then decides).
fn grow_holed(p: &Polygon<f64>, delta: f64) -> Option<MultiPolygon<f64>> {
    use geo::orient::{Direction, Orient};
    let outline = MultiPolygon::new(vec![exterior_only(p)]);
    let grown = clipper_offset(&outline, delta);
    let [outer] = &grown.0[..] else {
        return None;
    };
    let mut holes = outer.interiors().to_vec();
    for h in p.interiors() {
        let hole = MultiPolygon::new(vec![Polygon::new(h.clone(), Vec::new())]);
        for q in clipper_offset(&hole, -delta).0 {
            if !q.interiors().is_empty() {
                return None;
            }
            holes.push(q.exterior().clone());
        }
    }
    let out = Polygon::new(outer.exterior().clone(), holes).orient(Direction::Default);
    Some(MultiPolygon::new(vec![out]))
}

/// `mp` without the holes that growing it by `delta` closes (`None` when it has none): a
/// hole narrower than `2 delta` in X or Y has no point farther than `delta` from its edge.
/// Clipper offsets every hole and then resolves where they vanish, which for thousands of
/// them is quadratic: a damaged file's bridge regions over sparse infill, 4 548 holes, took
/// 2.9 s to grow by a millimetre, once for each of ten regions near them.
fn without_closing_holes(mp: &MultiPolygon<f64>, delta: f64) -> Option<MultiPolygon<f64>> {
    use geo::BoundingRect;
    let closes = |r: &geo::LineString<f64>| {
        r.bounding_rect()
            .is_none_or(|b| b.width().min(b.height()) < 2.0 * delta)
    };
    if !mp.0.iter().any(|p| p.interiors().iter().any(closes)) {
        return None;
    }
    Some(MultiPolygon::new(
        mp.0.iter()
            .map(|p| {
                geo::Polygon::new(
                    p.exterior().clone(),
                    p.interiors()
                        .iter()
                        .filter(|r| !closes(r))
                        .cloned()
                        .collect(),
                )
            })
            .collect(),
    ))
}

/// Largest distance (mm) by which [`margin`] may move an outline before growing it.
pub const MARGIN_SIMPLIFY: f64 = 0.01;

/// `mp` grown by `delta` mm as a margin (what lies near a zone): its outline is simplified
/// first, by [`MARGIN_SIMPLIFY`]. A rewritten zone's outline carries the round joins of the
/// openings that made it, thousands of points along a bowl's thin ring, and growing them all
/// by 1.5 mm made offsets whose self-intersections cost tens of milliseconds a layer (and
/// the booleans with them ten times that); the simplified outline grows in a millisecond.
pub fn margin(mp: &MultiPolygon<f64>, delta: f64) -> MultiPolygon<f64> {
    offset(&geo::Simplify::simplify(mp, MARGIN_SIMPLIFY), delta)
}

/// [`offset`] of the far-apart parts of `mp` separately, on all cores: growing parts that stay
/// apart cannot merge, so the union Clipper would make is their concatenation. The same
/// shapes as [`offset`], in another polygon order.
pub fn offset_parts(mp: &MultiPolygon<f64>, delta: f64) -> MultiPolygon<f64> {
    use geo::BoundingRect;
    use rayon::prelude::*;
    // Round joins lie on the arc; the margin covers Clipper's integer rounding.
    let reach = delta.max(0.0) + 1e-3;
    let boxes: Option<Vec<Box2>> =
        mp.0.iter()
            .map(|p| {
                let b = p.bounding_rect()?;
                Some((
                    [b.min().x - reach, b.min().y - reach],
                    [b.max().x + reach, b.max().y + reach],
                ))
            })
            .collect();
    let groups = match boxes {
        Some(b) if mp.0.len() > 1 => box_groups(&b),
        _ => return offset(mp, delta),
    };
    if groups.len() <= 1 {
        return offset(mp, delta);
    }
    let parts: Vec<MultiPolygon<f64>> = groups
        .par_iter()
        .map(|g| {
            offset(
                &MultiPolygon::new(g.iter().map(|&i| mp.0[i].clone()).collect()),
                delta,
            )
        })
        .collect();
    MultiPolygon::new(parts.into_iter().flat_map(|m| m.0).collect())
}

/// The polygons of a set indexed by bounding box, for many queries against one set (a plate's
/// layer has hundreds of parts, and thousands of strands ask which one holds them). Polygons
/// whose box is not finite (an R-tree cannot order NaN) are answered for every query.
pub struct BoxIndex {
    tree: rstar::RTree<
        rstar::primitives::GeomWithData<rstar::primitives::Rectangle<[f64; 2]>, usize>,
    >,
    odd: Vec<usize>,
}

impl BoxIndex {
    pub fn new(set: &MultiPolygon<f64>) -> BoxIndex {
        use geo::BoundingRect;
        use rstar::primitives::{GeomWithData, Rectangle};
        let mut boxes = Vec::with_capacity(set.0.len());
        let mut odd = Vec::new();
        for (i, p) in set.0.iter().enumerate() {
            let Some(b) = p.bounding_rect() else {
                continue;
            };
            let (lo, hi) = ([b.min().x, b.min().y], [b.max().x, b.max().y]);
            if lo.iter().chain(&hi).all(|v| v.is_finite()) {
                boxes.push(GeomWithData::new(Rectangle::from_corners(lo, hi), i));
            } else {
                odd.push(i);
            }
        }
        BoxIndex {
            tree: rstar::RTree::bulk_load(boxes),
            odd,
        }
    }

    /// Indices of the polygons whose boxes meet the box `lo`..`hi`.
    pub fn meeting(&self, lo: [f64; 2], hi: [f64; 2]) -> impl Iterator<Item = usize> + '_ {
        self.tree
            .locate_in_envelope_intersecting(&rstar::AABB::from_corners(lo, hi))
            .map(|g| g.data)
            .chain(self.odd.iter().copied())
    }

    /// Whether the point lies in a polygon of `set`, the set this index was built from.
    pub fn contains(&self, set: &MultiPolygon<f64>, x: f64, y: f64) -> bool {
        use geo::Contains;
        let pt = geo::Point::new(x, y);
        self.meeting([x, y], [x, y]).any(|i| set.0[i].contains(&pt))
    }
}

/// An axis-aligned box: lower and upper corners.
pub type Box2 = ([f64; 2], [f64; 2]);

/// Groups of boxes such that two boxes that meet are always in one group (a group may also
/// take a box that only meets its members' bounding box): the indices of each group, groups in
/// the order of their leftmost box and members by their left edges. Boxes with a NaN or
/// infinite corner all go to one group of their own, last.
pub fn box_groups(boxes: &[Box2]) -> Vec<Vec<usize>> {
    let finite = |b: &Box2| b.0.iter().chain(&b.1).all(|v| v.is_finite());
    let mut order: Vec<usize> = (0..boxes.len()).filter(|&i| finite(&boxes[i])).collect();
    let odd: Vec<usize> = (0..boxes.len()).filter(|&i| !finite(&boxes[i])).collect();
    order.sort_unstable_by(|&a, &b| boxes[a].0[0].total_cmp(&boxes[b].0[0]));
    // Sweep in x over the sorted boxes (positions in `order`): a group whose box ends left of
    // the next box can take no more. Every merge points the old root at a later position.
    let mut parent: Vec<usize> = (0..order.len()).collect();
    let mut open: Vec<(usize, Box2)> = Vec::new();
    for (n, &i) in order.iter().enumerate() {
        let (lo, hi) = boxes[i];
        open.retain(|g| g.1 .1[0] >= lo[0]);
        let (mut glo, mut ghi) = (lo, hi);
        open.retain(|&(root, (a, b))| {
            let meets = a[0] <= hi[0] && b[0] >= lo[0] && a[1] <= hi[1] && b[1] >= lo[1];
            if meets {
                parent[root] = n;
                glo = [glo[0].min(a[0]), glo[1].min(a[1])];
                ghi = [ghi[0].max(b[0]), ghi[1].max(b[1])];
            }
            !meets
        });
        open.push((n, (glo, ghi)));
    }
    let mut root = parent;
    for n in (0..root.len()).rev() {
        root[n] = root[root[n]];
    }
    let mut group_of: std::collections::HashMap<usize, usize> = Default::default();
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for (n, &i) in order.iter().enumerate() {
        let g = *group_of.entry(root[n]).or_insert_with(|| {
            groups.push(Vec::new());
            groups.len() - 1
        });
        groups[g].push(i);
    }
    if !odd.is_empty() {
        groups.push(odd);
    }
    groups
}

/// Largest distance (mm) between a loop front's round joins and the true offset. A front is
/// grown dozens of times, so its vertex count sets the cost of planning; 0.02 mm is a tenth
/// of what a printer positions to and keeps fronts light.
pub const FRONT_TOLERANCE: f64 = 0.02;

/// Whether two boxes come within `gap` of each other (0: they touch or overlap); a missing
/// box (no points) is taken as near anything.
pub fn boxes_within(a: Option<&geo::Rect<f64>>, b: Option<&geo::Rect<f64>>, gap: f64) -> bool {
    match (a, b) {
        (Some(a), Some(b)) => {
            a.min().x - gap <= b.max().x
                && b.min().x - gap <= a.max().x
                && a.min().y - gap <= b.max().y
                && b.min().y - gap <= a.max().y
        }
        _ => true,
    }
}

/// Bounding box of a polyline; `None` when it has no point.
pub fn points_box(points: &[[f64; 2]]) -> Option<geo::Rect<f64>> {
    let first = points.first()?;
    let (mut lo, mut hi) = (*first, *first);
    for q in points {
        lo = [lo[0].min(q[0]), lo[1].min(q[1])];
        hi = [hi[0].max(q[0]), hi[1].max(q[1])];
    }
    Some(geo::Rect::new(
        geo::coord! {x: lo[0], y: lo[1]},
        geo::coord! {x: hi[0], y: hi[1]},
    ))
}

/// Offsets of one area by growing distances, each as [`offset`] makes it (round joins).
///
/// Up to [`Growth::STAGE`] the area is offset directly; farther, from the area already
/// grown by whole stages (kept, one per stage), by what remains. A round offset is a
/// Minkowski sum with a disc, so growing by a then b is growing by a + b, and the grown area
/// is smooth: its concavities narrower than a stage are filled. Offsetting a jagged outline
/// (800 points) by 80 mm directly made every vertex's arc cross every other's: 0.4 ms per mm
/// of distance, a thin region of a damaged file planned for a minute.
pub struct Growth<'a> {
    source: &'a MultiPolygon<f64>,
    stages: Vec<MultiPolygon<f64>>,
}

impl<'a> Growth<'a> {
    /// Distance (mm) of each stage.
    pub const STAGE: f64 = 2.0;
    /// Simplification of each stage (mm): far under the offsets' own arc tolerance, so that
    /// the points of the stages' arcs do not pile up from one stage to the next.
    const STAGE_SIMPLIFY: f64 = 1e-4;

    pub fn new(source: &'a MultiPolygon<f64>) -> Growth<'a> {
        Growth {
            source,
            stages: Vec::new(),
        }
    }

    /// The source grown by `delta` mm.
    pub fn at(&mut self, delta: f64) -> MultiPolygon<f64> {
        if delta <= Self::STAGE || !delta.is_finite() {
            return offset(self.source, delta);
        }
        // Whole stages below `delta`, at least one, and at most what a plate's extent needs.
        let n = ((delta / Self::STAGE).ceil() as usize - 1).clamp(1, 10_000);
        while self.stages.len() < n {
            let grown = match self.stages.last() {
                Some(last) => offset(last, Self::STAGE),
                None => offset(self.source, Self::STAGE),
            };
            self.stages
                .push(geo::Simplify::simplify(&grown, Self::STAGE_SIMPLIFY));
        }
        offset(&self.stages[n - 1], delta - n as f64 * Self::STAGE)
    }
}

/// Grows `front` by `step` and cuts it back to `allowed`, with Clipper's exact integer
/// arithmetic and a light simplification, so that repeating it keeps the front clean and its
/// vertex count bounded (a float boolean engine snaps to its own grid and adds jitter).
pub fn grow_within(
    front: &MultiPolygon<f64>,
    step: f64,
    allowed: &MultiPolygon<f64>,
) -> MultiPolygon<f64> {
    use geo::Simplify;
    if front.0.is_empty() || allowed.0.is_empty() {
        return MultiPolygon::new(Vec::new());
    }
    let grown = front.offset(
        step,
        JoinType::Round(FRONT_TOLERANCE * CLIPPER_SCALE),
        EndType::ClosedPolygon,
        CLIPPER_SCALE,
    );
    let cut = Clipper::intersection(&grown, allowed, CLIPPER_SCALE);
    Simplify::simplify(&cut, FRONT_TOLERANCE / 2.0)
}

/// The cell (0 to `n - 1`) of a square grid starting at `origin` that holds `v`.
///
/// `as` saturates (a negative or NaN value is 0) and truncates, which for what is left is the
/// floor: the same cell as `floor().max(0.0)`, without a call to libm's floor.
pub(crate) fn cell_of(v: f64, origin: f64, cell: f64, n: usize) -> usize {
    (((v - origin) / cell) as usize).min(n - 1)
}

/// [`cell_of`] with the cell size given as its inverse: a multiplication where the hot
/// grids would divide. Monotone in `v` like `cell_of` (all a grid needs: an item entered over
/// a range of cells and a query over a range meet wherever the ranges of values do), though
/// not always the same cell.
pub(crate) fn cell_of_inv(v: f64, origin: f64, inv_cell: f64, n: usize) -> usize {
    (((v - origin) * inv_cell) as usize).min(n - 1)
}

/// Grid buckets of (cell, item) entries over `cells` cells: `start` (cell `c` holds
/// `items[start[c]..start[c + 1]]`) and `items`, each cell's items in entry order.
///
/// Counts, then each cell's end by a running sum, then each item placed by counting its
/// cell's end down (in reverse, so that a cell keeps its items in order): the ends become the
/// starts, with no second array. The sum runs in a register: the plain
/// `start[i + 1] += start[i]` was most of the time on a plate's grid.
pub(crate) fn buckets(cells: usize, entries: &[(u32, u32)]) -> (Vec<u32>, Vec<u32>) {
    let mut start = vec![0u32; cells + 1];
    for &(c, _) in entries {
        start[c as usize] += 1;
    }
    let mut acc = 0u32;
    for v in start.iter_mut() {
        acc += *v;
        *v = acc;
    }
    let mut items = vec![0; entries.len()];
    for &(c, i) in entries.iter().rev() {
        let at = &mut start[c as usize];
        *at -= 1;
        items[*at as usize] = i;
    }
    (start, items)
}

/// Morphological opening: removes every part narrower than `2 r`, keeps the rest's shape
/// (up to rounding of convex corners by `r`).
pub fn opening(mp: &MultiPolygon<f64>, r: f64) -> MultiPolygon<f64> {
    if r <= 0.0 {
        return mp.clone();
    }
    offset(&offset(mp, -r), r)
}

/// Morphological closing: fills every gap and notch narrower than `2 r`, keeps the rest's
/// shape (up to rounding of concave corners by `r`).
pub fn closing(mp: &MultiPolygon<f64>, r: f64) -> MultiPolygon<f64> {
    if r <= 0.0 {
        return mp.clone();
    }
    offset(&offset(mp, r), -r)
}

/// A polyline in mm.
pub type Polyline = Vec<[f64; 2]>;

/// Length of a polyline (mm).
pub fn polyline_length(p: &[[f64; 2]]) -> f64 {
    p.windows(2)
        .map(|w| ((w[1][0] - w[0][0]).powi(2) + (w[1][1] - w[0][1]).powi(2)).sqrt())
        .sum()
}

/// Where on the segment `a`-`b` the point nearest `p` lies: the parameter `t` in 0..=1 and
/// the point.
pub fn nearest_on_segment(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> (f64, [f64; 2]) {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (t, [a[0] + t * dx, a[1] + t * dy])
}

/// Whether segments `a`-`b` and `c`-`d` come within `gap` of each other (crossing counts).
pub fn segments_within(a: [f64; 2], b: [f64; 2], c: [f64; 2], d: [f64; 2], gap: f64) -> bool {
    let cross = |o: [f64; 2], p: [f64; 2], q: [f64; 2]| {
        (p[0] - o[0]) * (q[1] - o[1]) - (p[1] - o[1]) * (q[0] - o[0])
    };
    let (d1, d2) = (cross(a, b, c), cross(a, b, d));
    let (d3, d4) = (cross(c, d, a), cross(c, d, b));
    if d1 * d2 < 0.0 && d3 * d4 < 0.0 {
        return true;
    }
    let g2 = gap * gap;
    let near = |p: [f64; 2], s: [f64; 2], e: [f64; 2]| {
        let q = nearest_on_segment(p, s, e).1;
        (q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2) <= g2
    };
    near(a, c, d) || near(b, c, d) || near(c, a, b) || near(d, a, b)
}

/// Whether polylines `a` and `b` come within `gap` of each other anywhere. Segment pairs
/// whose boxes lie farther apart are passed over.
pub fn polylines_within(a: &[[f64; 2]], b: &[[f64; 2]], gap: f64) -> bool {
    let bb = match points_box(b) {
        Some(r) => r,
        None => return false,
    };
    let seg_box = |p: [f64; 2], q: [f64; 2]| {
        geo::Rect::new(
            geo::coord! { x: p[0], y: p[1] },
            geo::coord! { x: q[0], y: q[1] },
        )
    };
    for s in a.windows(2) {
        let sb = seg_box(s[0], s[1]);
        if !boxes_within(Some(&sb), Some(&bb), gap) {
            continue;
        }
        for t in b.windows(2) {
            if boxes_within(Some(&sb), Some(&seg_box(t[0], t[1])), gap)
                && segments_within(s[0], s[1], t[0], t[1], gap)
            {
                return true;
            }
        }
    }
    false
}

/// The parts of `lines` inside `area` (or outside it, with `inside` false).
pub fn clip_lines(lines: &[Polyline], area: &MultiPolygon<f64>, inside: bool) -> Vec<Polyline> {
    use geo::{BooleanOps, LineString, MultiLineString};
    let mls = MultiLineString::new(
        lines
            .iter()
            .filter(|l| l.len() >= 2)
            .map(|l| LineString::from(l.iter().map(|p| (p[0], p[1])).collect::<Vec<_>>()))
            .collect(),
    );
    if mls.0.is_empty() {
        return Vec::new();
    }
    if area.0.is_empty() {
        return if inside { Vec::new() } else { lines.to_vec() };
    }
    area.clip(&mls, !inside)
        .0
        .into_iter()
        .map(|ls| ls.0.into_iter().map(|c| [c.x, c.y]).collect::<Polyline>())
        .filter(|l| l.len() >= 2)
        .collect()
}

/// Every ring (exteriors and holes) of a polygon set as a closed polyline.
pub fn rings(mp: &MultiPolygon<f64>) -> Vec<Polyline> {
    mp.0.iter()
        .flat_map(|p| std::iter::once(p.exterior()).chain(p.interiors()))
        .map(|r| r.0.iter().map(|c| [c.x, c.y]).collect::<Polyline>())
        .filter(|r| r.len() >= 3)
        .collect()
}

pub fn difference(a: &MultiPolygon<f64>, b: &MultiPolygon<f64>) -> MultiPolygon<f64> {
    if a.0.is_empty() || b.0.is_empty() {
        return a.clone();
    }
    geo::BooleanOps::difference(a, b)
}

pub fn union(a: &MultiPolygon<f64>, b: &MultiPolygon<f64>) -> MultiPolygon<f64> {
    if a.0.is_empty() {
        return b.clone();
    }
    if b.0.is_empty() {
        return a.clone();
    }
    geo::BooleanOps::union(a, b)
}

/// The union of `sets`. Sets whose boxes stay apart cannot meet: their polygons are taken as
/// they are, and only the groups whose boxes meet ([`box_groups`]) are joined, so that the
/// zones of a plate's parts cost one boolean each at most, not one per part before (a fold
/// over sixteen caps took a tenth of the rewrite's time).
pub fn union_all(sets: &[&MultiPolygon<f64>]) -> MultiPolygon<f64> {
    use geo::BoundingRect;
    let boxes: Vec<Box2> = sets
        .iter()
        .map(|s| match s.bounding_rect() {
            Some(b) => ([b.min().x, b.min().y], [b.max().x, b.max().y]),
            // Empty: a box that meets nothing.
            None => ([f64::NAN; 2], [f64::NAN; 2]),
        })
        .collect();
    let mut out = Vec::new();
    for group in box_groups(&boxes) {
        let joined = group
            .iter()
            .fold(MultiPolygon(Vec::new()), |acc, &i| union(&acc, sets[i]));
        out.extend(joined.0);
    }
    MultiPolygon(out)
}

pub fn intersection(a: &MultiPolygon<f64>, b: &MultiPolygon<f64>) -> MultiPolygon<f64> {
    if a.0.is_empty() || b.0.is_empty() {
        return MultiPolygon::new(Vec::new());
    }
    geo::BooleanOps::intersection(a, b)
}

/// The area of each polygon of `parts` (disjoint, as a boolean's output is) that lies in
/// `within`. One boolean for all the parts, its pieces then credited to the part holding
/// them: a hollow torus's bottom, its solid infill ending in a saw along the void, has
/// hundreds of notches, and a boolean of each with the whole layer below took 100 ms a
/// region. Parts meeting at a corner can come out of the boolean as one piece: those parts
/// are measured on their own.
pub fn shares_within(parts: &MultiPolygon<f64>, within: &MultiPolygon<f64>) -> Vec<f64> {
    use geo::{Area, BoundingRect, Intersects};
    let mut share = vec![Some(0.0); parts.0.len()];
    let index = BoxIndex::new(parts);
    for piece in &intersection(parts, within).0 {
        let Some(b) = piece.bounding_rect() else {
            continue;
        };
        let mut holders = index
            .meeting([b.min().x, b.min().y], [b.max().x, b.max().y])
            .filter(|&i| parts.0[i].intersects(piece));
        match (holders.next(), holders.next()) {
            (Some(i), None) => {
                if let Some(s) = &mut share[i] {
                    *s += piece.unsigned_area();
                }
            }
            (Some(i), Some(j)) => {
                for k in [i, j].into_iter().chain(holders) {
                    share[k] = None;
                }
            }
            (None, _) => {}
        }
    }
    share
        .into_iter()
        .zip(&parts.0)
        .map(|(s, p)| {
            s.unwrap_or_else(|| {
                intersection(&MultiPolygon::new(vec![p.clone()]), within).unsigned_area()
            })
        })
        .collect()
}

/// The polygons of `mp` whose bounding box comes within `margin` of `rect`.
///
/// Booleans and point tests cost in proportion to every vertex they are given; a region of
/// a plate of many parts only needs the parts around it.
pub fn near(mp: &MultiPolygon<f64>, rect: &geo::Rect<f64>, margin: f64) -> MultiPolygon<f64> {
    MultiPolygon::new(near_refs(mp, rect, margin).into_iter().cloned().collect())
}

/// [`near`], borrowed: the polygons in their order.
pub fn near_refs<'a>(
    mp: &'a MultiPolygon<f64>,
    rect: &geo::Rect<f64>,
    margin: f64,
) -> Vec<&'a Polygon<f64>> {
    use geo::BoundingRect;
    let (lo, hi) = (rect.min(), rect.max());
    mp.0.iter()
        .filter(|p| {
            p.bounding_rect().is_some_and(|b| {
                b.min().x <= hi.x + margin
                    && b.max().x >= lo.x - margin
                    && b.min().y <= hi.y + margin
                    && b.max().y >= lo.y - margin
            })
        })
        .collect()
}

/// A polygon's exterior as a polygon without holes.
pub fn exterior_only(p: &Polygon<f64>) -> Polygon<f64> {
    Polygon::new(p.exterior().clone(), Vec::new())
}

#[cfg(test)]
pub(crate) mod testutil {
    use geo::{coord, LineString, MultiPolygon, Polygon};

    pub fn rect(x0: f64, y0: f64, x1: f64, y1: f64) -> Polygon<f64> {
        Polygon::new(
            LineString::new(vec![
                coord! {x: x0, y: y0},
                coord! {x: x1, y: y0},
                coord! {x: x1, y: y1},
                coord! {x: x0, y: y1},
                coord! {x: x0, y: y0},
            ]),
            Vec::new(),
        )
    }

    pub fn mp(p: Vec<Polygon<f64>>) -> MultiPolygon<f64> {
        MultiPolygon::new(p)
    }

    /// A fixed sequence of numbers in [0, 1) (a linear congruential generator): tests that
    /// draw many cases draw the same ones every run.
    pub fn lcg(mut seed: u64) -> impl FnMut() -> f64 {
        move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 33) as f64 / (1u64 << 31) as f64
        }
    }
}

#[cfg(test)]
mod tests {
    use super::testutil::*;
    use super::*;
    use geo::Area;

    #[test]
    fn each_part_s_share_within_an_area_is_its_own_boolean_s() {
        // Three notches: one half inside `within`, one whole, one outside; two more meeting
        // at a corner, a quarter of each inside (the boolean's pieces meet there too).
        let parts = mp(vec![
            rect(0.0, 0.0, 1.0, 2.0),
            rect(2.0, 0.0, 3.0, 1.0),
            rect(5.0, 5.0, 6.0, 6.0),
            rect(0.0, 4.0, 1.0, 5.0),
            rect(1.0, 5.0, 2.0, 6.0),
        ]);
        let within = mp(vec![rect(-1.0, -1.0, 4.0, 1.0), rect(0.5, 4.5, 1.5, 5.5)]);
        let got = shares_within(&parts, &within);
        for (p, share) in parts.0.iter().zip(&got) {
            let own = intersection(&mp(vec![p.clone()]), &within).unsigned_area();
            assert!((share - own).abs() < 1e-9, "{share} vs {own}");
        }
        let want = [1.0, 1.0, 0.0, 0.25, 0.25];
        for (g, w) in got.iter().zip(want) {
            assert!((g - w).abs() < 0.02, "{got:?}");
        }
    }

    /// Growing a plate pierced by many small holes: the holes it closes are left out before
    /// Clipper sees them, and the result is what Clipper gives growing it with them (every
    /// hole narrower than twice the growth closes; a wider one stays open, narrowed).
    #[test]
    fn growing_closes_small_holes_without_offsetting_them() {
        use geo::{coord, Contains, LineString, Polygon};
        let square = |x: f64, y: f64, s: f64| {
            LineString::new(vec![
                coord! {x: x, y: y},
                coord! {x: x, y: y + s},
                coord! {x: x + s, y: y + s},
                coord! {x: x + s, y: y},
                coord! {x: x, y: y},
            ])
        };
        let mut holes: Vec<LineString<f64>> = Vec::new();
        for i in 0..15 {
            for j in 0..15 {
                holes.push(square(1.0 + i as f64, 1.0 + j as f64, 0.5));
            }
        }
        // One hole 3 mm across, which growing by 1 mm narrows to 1 mm.
        holes.push(square(20.0, 5.0, 3.0));
        let plate = mp(vec![Polygon::new(
            rect(0.0, 0.0, 25.0, 17.0).exterior().clone(),
            holes,
        )]);
        let pruned = without_closing_holes(&plate, 1.0).expect("holes close");
        assert_eq!(pruned.0[0].interiors().len(), 1);
        let grown = offset(&plate, 1.0);
        let by_clipper = plate.offset(
            1.0,
            JoinType::Round(ARC_TOLERANCE * CLIPPER_SCALE),
            EndType::ClosedPolygon,
            CLIPPER_SCALE,
        );
        assert_eq!(grown.0.len(), 1);
        assert_eq!(grown.0[0].interiors().len(), 1);
        assert_eq!(by_clipper.0[0].interiors().len(), 1);
        assert!((grown.unsigned_area() - by_clipper.unsigned_area()).abs() < 1e-9);
        assert!(!grown.contains(&geo::Point::new(21.5, 6.5)));
        assert!(grown.contains(&geo::Point::new(5.25, 5.25)));
        // Shrinking keeps every hole (none closes).
        assert!(without_closing_holes(&plate, -0.1).is_none());
        assert_eq!(offset(&plate, -0.1).0[0].interiors().len(), 226);
    }

    /// A saw-toothed outline (the teeth 0.3 mm deep, 0.2 mm apart, as a damaged file's
    /// layer may print) grown far: by stages, the same area as one offset to within the
    /// offsets' arc tolerance along its outline, near and far.
    #[test]
    fn growing_by_stages_gives_the_area_one_offset_gives() {
        use geo::{coord, LineString, Polygon};
        let mut pts = Vec::new();
        for i in 0..=100 {
            let x = i as f64 * 0.2;
            pts.push(coord! {x: x, y: if i % 2 == 0 { 0.0 } else { 0.3 }});
        }
        pts.push(coord! {x: 20.0, y: 5.0});
        pts.push(coord! {x: 0.0, y: 5.0});
        pts.push(coord! {x: 0.0, y: 0.0});
        let saw = mp(vec![Polygon::new(LineString::new(pts), Vec::new())]);
        let mut growth = Growth::new(&saw);
        for d in [0.5, 2.0, 2.1, 4.0, 7.3, 30.0] {
            let staged = growth.at(d);
            let direct = offset(&saw, d);
            let outline = 2.0 * (20.0 + 5.0 + 4.0 * d);
            let apart = difference(&staged, &direct).unsigned_area()
                + difference(&direct, &staged).unsigned_area();
            assert!(
                apart <= 2.0 * ARC_TOLERANCE * outline,
                "grown by {d}: {apart:.4} mm2 apart ({:.1} vs {:.1})",
                staged.unsigned_area(),
                direct.unsigned_area()
            );
        }
        // One stage per 2 mm, the last short of 30 mm.
        assert_eq!(growth.stages.len(), 14);
    }

    #[test]
    fn cells_by_the_inverse_never_go_backwards() {
        // A grid needs only monotone cells: values in order land in cells in order.
        let (origin, cell) = (-3.7, 0.3);
        let mut v: Vec<f64> = (0..20_000).map(|i| origin + i as f64 * 0.0371).collect();
        v.extend([f64::NAN, -1e300, 1e300, origin, origin - 1e-12]);
        v.sort_by(f64::total_cmp);
        let cells: Vec<usize> = v
            .iter()
            .filter(|x| !x.is_nan())
            .map(|&x| cell_of_inv(x, origin, 1.0 / cell, 2000))
            .collect();
        assert!(cells.windows(2).all(|w| w[0] <= w[1]));
        assert_eq!(cells[0], 0);
        assert_eq!(*cells.last().unwrap(), 1999);
        assert_eq!(cell_of_inv(f64::NAN, origin, 1.0 / cell, 10), 0);
        // Within one cell of the dividing version everywhere.
        for &x in &v {
            let (a, b) = (
                cell_of(x, origin, cell, 2000),
                cell_of_inv(x, origin, 1.0 / cell, 2000),
            );
            assert!(a.abs_diff(b) <= 1, "{x}: {a} vs {b}");
        }
    }

    #[test]
    fn meeting_boxes_share_a_group() {
        let b = |x0: f64, y0: f64, x1: f64, y1: f64| ([x0, y0], [x1, y1]);
        let boxes = [
            b(20.0, 0.0, 21.0, 1.0),
            b(0.0, 0.0, 2.0, 2.0),
            b(1.5, 1.5, 3.0, 3.0),
            b(2.5, 0.0, 4.0, 0.5),
            b(0.0, 10.0, 1.0, 11.0),
            b(f64::NAN, 0.0, 1.0, 1.0),
        ];
        let groups = box_groups(&boxes);
        let group = |i: usize| groups.iter().position(|g| g.contains(&i)).unwrap();
        assert_eq!(groups.iter().map(Vec::len).sum::<usize>(), boxes.len());
        assert_eq!(group(1), group(2), "overlapping boxes");
        assert_ne!(group(0), group(1), "far apart");
        assert_ne!(group(4), group(1), "far apart");
        assert_eq!(groups.last(), Some(&vec![5]), "a NaN box alone, last");
    }

    #[test]
    fn a_union_of_many_sets_is_their_union() {
        // Two overlapping squares, one apart, one touching the first along an edge, one empty.
        let a = mp(vec![rect(0.0, 0.0, 5.0, 5.0)]);
        let b = mp(vec![rect(3.0, 3.0, 8.0, 8.0)]);
        let c = mp(vec![rect(30.0, 0.0, 35.0, 5.0)]);
        let d = mp(vec![rect(5.0, 0.0, 6.0, 1.0)]);
        let e = MultiPolygon(Vec::new());
        let all = union_all(&[&a, &c, &e, &b, &d]);
        let folded = [&a, &b, &c, &d]
            .iter()
            .fold(e.clone(), |acc, s| union(&acc, s));
        assert!((all.unsigned_area() - folded.unsigned_area()).abs() < 1e-9);
        assert!((all.unsigned_area() - (25.0 + 25.0 - 4.0 + 25.0 + 1.0)).abs() < 1e-9);
        // Overlaps are joined: no point of the plane is counted twice.
        assert_eq!(all.0.len(), 2, "{all:?}");
        assert!(union_all(&[]).0.is_empty());
    }

    #[test]
    fn a_margin_is_the_offset_within_the_simplification() {
        // A thin ring whose outlines zigzag by 4 um, as booleans leave a gradual overhang's.
        let ring = |r: f64| {
            geo::LineString::new(
                (0..=2000)
                    .map(|i| {
                        let a = i as f64 / 2000.0 * std::f64::consts::TAU;
                        let r = r + if i % 2 == 0 { 0.004 } else { 0.0 };
                        geo::coord! {x: r * a.cos(), y: r * a.sin()}
                    })
                    .collect(),
            )
        };
        let m = mp(vec![Polygon::new(ring(20.3), vec![ring(20.0)])]);
        let grown = margin(&m, 1.5);
        let (lo, hi) = (
            offset(&m, 1.5 - MARGIN_SIMPLIFY),
            offset(&m, 1.5 + MARGIN_SIMPLIFY),
        );
        assert!(difference(&lo, &grown).unsigned_area() < 1e-6);
        assert!(difference(&grown, &hi).unsigned_area() < 1e-6);
        assert!(grown.unsigned_area() > 0.99 * offset(&m, 1.5).unsigned_area());
    }

    #[test]
    fn parts_offset_alone_give_what_one_offset_gives() {
        // Two squares 1 mm apart merge when grown by 0.6 mm; a third stays apart.
        let m = mp(vec![
            rect(0.0, 0.0, 5.0, 5.0),
            rect(6.0, 0.0, 11.0, 5.0),
            rect(30.0, 0.0, 35.0, 5.0),
        ]);
        for delta in [0.3, 0.6, -0.5] {
            let (parts, whole) = (offset_parts(&m, delta), offset(&m, delta));
            assert_eq!(parts.0.len(), whole.0.len(), "delta {delta}");
            assert!(
                (parts.unsigned_area() - whole.unsigned_area()).abs() < 1e-9,
                "delta {delta}"
            );
        }
        assert_eq!(offset_parts(&m, 0.6).0.len(), 2);
    }

    #[test]
    fn offset_grows_and_shrinks() {
        let sq = mp(vec![rect(0.0, 0.0, 10.0, 10.0)]);
        let grown = offset(&sq, 1.0);
        // 10x10 grown by 1 with round corners: 100 + 4*10 + pi.
        let expected = 100.0 + 40.0 + std::f64::consts::PI;
        assert!((grown.unsigned_area() - expected).abs() < 0.05);
        let shrunk = offset(&sq, -1.0);
        assert!((shrunk.unsigned_area() - 64.0).abs() < 1e-6);
        assert!(offset(&sq, -6.0).0.is_empty());
    }

    #[test]
    fn a_plate_of_many_holes_grows_as_one_boolean_would() {
        use geo::{BooleanOps, Contains};
        // A 40 x 40 plate pierced by 10 x 10 round holes of 1.6 mm every 3.5 mm, one of them
        // small enough for the growth to close, and a bay its growth closes into a new hole.
        let circle = |c: [f64; 2], r: f64| -> geo::LineString<f64> {
            (0..=24)
                .map(|k| {
                    let a = std::f64::consts::TAU * (k % 24) as f64 / 24.0;
                    geo::coord! {x: c[0] + r * a.cos(), y: c[1] + r * a.sin()}
                })
                .collect()
        };
        let mut holes: Vec<geo::LineString<f64>> = Vec::new();
        for i in 0..10 {
            for j in 0..10 {
                let r = if i == 3 && j == 3 { 0.3 } else { 0.8 };
                holes.push(circle([3.0 + 3.5 * i as f64, 3.0 + 3.5 * j as f64], r));
            }
        }
        // The bay: a chamber 4 x 1.5 mm behind a mouth 0.8 mm wide in the top edge.
        let outline: geo::LineString<f64> = vec![
            (0.0, 0.0),
            (40.0, 0.0),
            (40.0, 40.0),
            (20.4, 40.0),
            (20.4, 38.0),
            (22.0, 38.0),
            (22.0, 36.5),
            (18.0, 36.5),
            (18.0, 38.0),
            (19.6, 38.0),
            (19.6, 40.0),
            (0.0, 40.0),
            (0.0, 0.0),
        ]
        .into();
        let plate = mp(vec![Polygon::new(outline, holes)]);
        let fast = offset(&plate, 0.5);
        let whole = clipper_offset(&plate, 0.5);
        assert_eq!(fast.0.len(), 1);
        // The same shape: 99 holes left (the small one closed) and the bay's chamber, equal
        // areas, and nothing of one outside the other but arcs' chords.
        assert_eq!(fast.0[0].interiors().len(), 100);
        assert_eq!(
            whole.0.iter().map(|q| q.interiors().len()).sum::<usize>(),
            100
        );
        let gap = BooleanOps::xor(&fast, &whole).unsigned_area();
        assert!(gap < 1e-3, "{gap}");
        // A hole's centre stays out, a point between holes in.
        assert!(!fast.contains(&geo::Point::new(6.5, 6.5)));
        assert!(fast.contains(&geo::Point::new(4.75, 4.75)));
        assert!(!fast.contains(&geo::Point::new(20.0, 37.25)));
        assert!(fast.contains(&geo::Point::new(20.0, 39.5)));
    }

    #[test]
    fn near_keeps_the_polygons_around_a_box() {
        let set = mp(vec![
            rect(0.0, 0.0, 1.0, 1.0),
            rect(5.0, 0.0, 6.0, 1.0),
            rect(20.0, 20.0, 21.0, 21.0),
        ]);
        let b = geo::Rect::new(geo::coord! {x: 2.0, y: 0.0}, geo::coord! {x: 3.0, y: 1.0});
        assert_eq!(near(&set, &b, 0.5).0.len(), 0);
        let kept = near(&set, &b, 2.0);
        assert_eq!(kept.0.len(), 2);
        assert!((kept.unsigned_area() - 2.0).abs() < 1e-9);
    }

    #[test]
    fn polylines_are_within_a_gap_where_any_two_of_their_segments_are() {
        // Crossing segments whose ends all lie far from the other one.
        assert!(segments_within(
            [0.0, -5.0],
            [0.0, 5.0],
            [-5.0, 0.0],
            [5.0, 0.0],
            0.1
        ));
        // Parallel, 1 mm apart.
        assert!(segments_within(
            [0.0, 0.0],
            [10.0, 0.0],
            [2.0, 1.0],
            [8.0, 1.0],
            1.0
        ));
        assert!(!segments_within(
            [0.0, 0.0],
            [10.0, 0.0],
            [2.0, 1.0],
            [8.0, 1.0],
            0.99
        ));
        // End to end along a line, 0.5 mm apart.
        assert!(!segments_within(
            [0.0, 0.0],
            [1.0, 0.0],
            [1.5, 0.0],
            [3.0, 0.0],
            0.49
        ));
        // A ring round a point far inside it is not near a short stroke at its centre,
        // though their boxes meet.
        let ring: Vec<[f64; 2]> = (0..=32)
            .map(|i| {
                let a = i as f64 / 32.0 * std::f64::consts::TAU;
                [10.0 * a.cos(), 10.0 * a.sin()]
            })
            .collect();
        let stroke = [[-1.0, 0.0], [1.0, 0.0]];
        assert!(!polylines_within(&ring, &stroke, 5.0));
        assert!(polylines_within(&ring, &[[-1.0, 0.0], [9.5, 0.0]], 0.6));
        assert!(!polylines_within(&ring, &[[0.0, 0.0]], 100.0));
    }

    #[test]
    fn opening_drops_thin_parts() {
        let thin = mp(vec![rect(0.0, 0.0, 10.0, 0.3), rect(0.0, 5.0, 10.0, 8.0)]);
        let opened = opening(&thin, 0.2);
        assert_eq!(opened.0.len(), 1);
        assert!((opened.unsigned_area() - 30.0).abs() < 0.1);
    }
}
