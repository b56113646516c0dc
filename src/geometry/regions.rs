//! Unsupported regions: sectC = sectB - sectA in the paper's terms.
//!
//! Input: the printed area of layer i-1 (sectA), layer i and its printed area (sectB).
//! Output: the parts of sectB farther than a tolerance from sectA, at least `min_width` wide
//! and `min_area` large, each classified by how its boundary is anchored:
//! - overhang: anchored along one connected stretch of its boundary;
//! - bridge: anchored along two or more separate stretches (a span between two supports);
//! - floating: anchored nowhere (an island in the air).
//!
//! The sliver rule: a region survives when a disc of diameter `min_width` fits in it (a
//! morphological opening by `min_width / 2` keeps something) and what survives covers at
//! least `min_area`. The defaults (a tenth of the external perimeter width, 0.2 mm2; the
//! rewrite takes a region under 1 mm2 only where the slicer's strands over it hang) keep the
//! thin rings of gradual overhangs: wherever the slicer's perimeter would hang more than half
//! its width (the tolerance) plus a tenth past the layer below. With 0.45 mm perimeters at
//! 0.2 mm layers that is every slope flatter than 50 degrees from vertical (0.27 mm of
//! overhang per layer); a ring of a sphere's underside or of a 60 degree arm is a region.

use geo::{
    coord, Area, BooleanOps, BoundingRect, Contains, Line, LineString, MultiPolygon, Point,
    Polygon, Rect,
};
use rstar::RTree;
use serde::Serialize;

use crate::layers::{Layer, Role};

use super::area::AreaOptions;
use super::{near, offset_parts, opening};

/// How far from the layer below a point may be and still count as supported.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Tolerance {
    /// Half the external perimeter width (the paper's rule of thumb for a bead's overhang).
    Auto,
    /// A fixed distance in mm.
    Distance(f64),
    /// An overhang angle from vertical in degrees: tolerance = layer height x tan(angle).
    Angle(f64),
}

/// Share of the external perimeter width that the narrowest region kept has by default.
/// A region is what lies beyond the tolerance (half that width): a ring the slicer's
/// perimeter hangs more than half its width past the layer below, plus this much.
pub const GRADUAL_SHARE: f64 = 0.1;

/// Regions reaching no farther than this many external perimeter widths from the layer below
/// are overhangs, however their edges touch it: they are the rings of gradual overhangs.
const THIN_REACH: f64 = 2.0;

/// Settings of region detection.
#[derive(Debug, Clone)]
pub struct DetectOptions {
    pub tolerance: Tolerance,
    /// Narrowest region kept (mm); `None` means a tenth of the external perimeter width ([`GRADUAL_SHARE`]).
    pub min_width: Option<f64>,
    /// Smallest region kept (mm2).
    pub min_area: f64,
    /// External perimeter width of the file (mm), for the defaults above.
    pub external_width: f64,
    pub area: AreaOptions,
    /// Try [`super::proof::supported`] before the polygon work (the results are the same
    /// either way; off to check that, and for a hollow part, see [`DetectOptions::for_file`]).
    pub prove: bool,
    /// How much the slicer drew the first layer in from the part's outline (mm; PrusaSlicer's
    /// `elefant_foot_compensation`): the first layer squashes out to the outline, so the
    /// layer on it is judged against its area grown by this much.
    pub first_layer_shrink: f64,
    /// How far fuzzy skin moves the walls' points off the outline (mm, either way; 0
    /// without it): the automatic tolerance grows by it (see [`DetectOptions::tolerance_at`]).
    pub fuzzy_skin: f64,
}

impl Default for DetectOptions {
    fn default() -> Self {
        DetectOptions {
            tolerance: Tolerance::Auto,
            min_width: None,
            min_area: 0.2,
            external_width: 0.45,
            area: AreaOptions::default(),
            prove: true,
            first_layer_shrink: 0.0,
            fuzzy_skin: 0.0,
        }
    }
}

impl DetectOptions {
    /// The defaults for a file sliced with `config`: its external perimeter width and
    /// elephant foot compensation, and whether its parts are hollow (`fill_density = 0%`).
    pub fn for_file(config: &crate::layers::SlicerConfig) -> DetectOptions {
        let hollow = config.fill_density() == Some(0.0);
        DetectOptions {
            external_width: config.external_perimeter_width(),
            first_layer_shrink: config.elephant_foot(),
            fuzzy_skin: config.fuzzy_skin(),
            area: AreaOptions {
                hollow,
                ..Default::default()
            },
            // The quick proof takes a part's inside as held (its step 3): not so in a hollow
            // part, where a roof's first layer spans air.
            prove: !hollow,
            ..Default::default()
        }
    }

    /// The tolerance in mm for a layer `height` thick. Automatic: half the external
    /// perimeter width, plus the fuzzy skin thickness where the file has fuzzy skin: its
    /// walls' points sit up to that far out of the outline and the layer below's up to that
    /// far in, so a vertical wall's perimeter stood out of the one below by more than the
    /// plain tolerance every few millimetres (a fuzzy tube by PrusaSlicer at 0.5 mm: 2663
    /// "gradual overhangs" rewritten, +905 s, and the texture smoothed where they were;
    /// with the thickness added, none). The price: a slope is rewritten from
    /// atan((w/2 + t) / h) from vertical on (69 deg at 0.45 mm, t 0.3 and 0.2 mm layers)
    /// instead of 48 deg. A tolerance given in mm or as an angle is taken as given.
    pub fn tolerance_at(&self, height: f64) -> f64 {
        match self.tolerance {
            Tolerance::Auto => self.external_width / 2.0 + self.fuzzy_skin.clamp(0.0, 2.0),
            Tolerance::Distance(d) => d.max(0.0),
            Tolerance::Angle(a) => height.max(0.0) * a.clamp(0.0, 89.9).to_radians().tan(),
        }
    }

    /// Narrowest region kept: by default a tenth of the external perimeter width, so the
    /// thin rings of gradual overhangs (each layer a little wider than the one below) are
    /// kept while numeric slivers along walls are not.
    pub fn min_width(&self) -> f64 {
        self.min_width
            .unwrap_or(GRADUAL_SHARE * self.external_width)
            .max(0.0)
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum RegionKind {
    Overhang,
    Bridge,
    Floating,
}

impl RegionKind {
    pub fn name(self) -> &'static str {
        match self {
            RegionKind::Overhang => "overhang",
            RegionKind::Bridge => "bridge",
            RegionKind::Floating => "floating",
        }
    }
}

/// What the slicer printed inside a region.
#[derive(Debug, Clone, Serialize)]
pub struct RoleExtrusion {
    pub role: &'static str,
    pub length_mm: f64,
    pub filament_mm: f64,
}

/// One unsupported region of one layer.
#[derive(Debug, Clone)]
pub struct Region {
    pub layer: usize,
    pub z: f64,
    pub height: f64,
    pub kind: RegionKind,
    pub polygon: Polygon<f64>,
    pub area: f64,
    /// Largest distance from a point of the region to the area printed below (mm).
    pub max_distance: f64,
    /// Length of the region's boundary that lies against the layer below (mm).
    pub anchored_length: f64,
    /// Number of separate anchored stretches.
    pub anchors: usize,
    /// The object most of the region's extrusions belong to.
    pub object: Option<u32>,
    /// Extrusions of the original file inside the region, by role.
    pub extrusions: Vec<RoleExtrusion>,
}

/// Spacing of the samples along a region's boundary when measuring anchoring (mm).
const ANCHOR_STEP: f64 = 0.2;
/// Most samples along one region's boundary: a boundary longer than this many steps (20 m
/// at [`ANCHOR_STEP`]: only a damaged file's strands, a move to X 99999, make one) is sampled
/// more sparsely, so a region's judgement costs bounded time (hours before, for 700 such
/// regions).
const MAX_ANCHOR_SAMPLES: f64 = 1.0e5;

/// [`ANCHOR_STEP`], or coarser for boundaries longer than [`MAX_ANCHOR_SAMPLES`] steps.
fn anchor_step<'a>(rings: impl IntoIterator<Item = &'a LineString<f64>>) -> f64 {
    let length: f64 = rings
        .into_iter()
        .flat_map(|r| r.0.windows(2))
        .map(|w| (w[1].x - w[0].x).hypot(w[1].y - w[0].y))
        .sum();
    ANCHOR_STEP.max(length / MAX_ANCHOR_SAMPLES)
}
/// Extra reach of the anchor zone beyond the tolerance, covering offset and opening rounding.
const ANCHOR_SLACK: f64 = 0.15;

/// Finds the unsupported regions of `layer`, whose printed area is `here`, over `below`.
pub fn find_regions(
    below: &MultiPolygon<f64>,
    layer: &Layer,
    here: &MultiPolygon<f64>,
    opts: &DetectOptions,
) -> Vec<Region> {
    // A layer that covers exactly what the one below covered (a straight wall, its footprint
    // shared) has nothing over air: skip the offsets and booleans.
    if here.0.is_empty() || here == below {
        return Vec::new();
    }
    let tol = opts.tolerance_at(layer.height);
    // Support material alone holds no region (see `support_only`), nor does a wipe tower: on a
    // layer that prints more than the part, only the islands where the part prints are
    // searched, and the rest's many lines are never grown and cut for nothing.
    let searched;
    let here = if layer.paths.iter().any(|p| !p.role.is_part()) {
        let part: Vec<Rect<f64>> = layer
            .paths
            .iter()
            .filter(|p| p.role.is_part())
            .filter_map(path_box)
            .collect();
        searched = MultiPolygon::new(
            here.0
                .iter()
                .filter(|q| {
                    q.bounding_rect()
                        .is_some_and(|b| part.iter().any(|pb| boxes_meet(&b, pb)))
                })
                .cloned()
                .collect(),
        );
        &searched
    } else {
        here
    };
    let raw = joined_across_slits(uncovered(here, below, tol), opts.external_width / 4.0);
    if raw.unsigned_area() < opts.min_area {
        return Vec::new();
    }
    let kept = opening(&raw, opts.min_width() / 2.0);
    let kept: Vec<Polygon<f64>> = kept
        .0
        .into_iter()
        .filter(|p| p.unsigned_area() >= opts.min_area)
        .collect();
    if kept.is_empty() {
        return Vec::new();
    }
    let boxes: Vec<Option<Rect<f64>>> = layer.paths.iter().map(path_box).collect();
    // Each region is described on its own (a plate's caps are 16 of them, 1.6 ms each):
    // on all cores, in order.
    use rayon::prelude::*;
    kept.into_par_iter()
        .map(|polygon| describe(polygon, below, tol + ANCHOR_SLACK, layer, &boxes, opts))
        // Support material over air is the slicer's business: support lines stacked over the
        // gaps of the support below, or its first layers hanging under a part's ledge. Only
        // the part is rewritten (a region of support alone would get loops over it and
        // nothing taken out).
        .filter(|r| !support_only(r, layer, &boxes))
        .collect()
}

/// [`find_regions`] on a layer below as the slicer printed it (not as poa rewrote it, whose
/// holes beside the zones are pockets the splice cut): sparse infill over a hole of the layer
/// below that this layer fills is the part's inside. One wall and infill printed every other
/// layer (PrusaSlicer's `infill_every_layers`, Cura's `infill_sparse_thickness`) leave the
/// layer below a ring of wall round nothing, which reads as a hole walled by the external
/// perimeter. A real hole is closed by bridging solid infill, never by sparse infill (a pin's
/// inside got ten loops where the combined infill went; the check found 13.6 mm of them in
/// air). Over a rewritten layer the filter changed which layers the cascade of a honeycomb
/// hull reached: 30-39 regions became 36-46.
pub fn find_regions_as_sliced(
    below: &MultiPolygon<f64>,
    layer: &Layer,
    here: &MultiPolygon<f64>,
    opts: &DetectOptions,
) -> Vec<Region> {
    let mut regions = find_regions(below, layer, here, opts);
    regions.retain(|r| !infill_in_a_hole(r, below, layer));
    regions
}

/// Whether sparse infill is all that prints a region lying in a hole of `below` (or nothing
/// does: the hole the printed area closed round a short stroke of infill along the wall).
/// A region no strand's centre line enters may still lie under a wall's bead: the thin ring
/// of a gradual overhang round a cavity (a dome shell's inner wall stepping in 0.3-0.45 mm a
/// layer) is the outer half of the wall's bead past the layer below's, and is kept.
fn infill_in_a_hole(r: &Region, below: &MultiPolygon<f64>, layer: &Layer) -> bool {
    use geo::InteriorPoint;
    let infill = Role::Infill.name();
    if r.extrusions.iter().any(|e| e.role != infill) {
        return false;
    }
    let Some(at) = r.polygon.interior_point() else {
        return false;
    };
    // The hole first: the bead test measures every wall segment of the layer against the
    // region (a bowl's thin ring, no hole: a twentieth of a plate of bowls' time).
    below.0.iter().any(|q| {
        q.interiors()
            .iter()
            .any(|h| Polygon::new(h.clone(), Vec::new()).contains(&at))
    }) && !(r.extrusions.is_empty() && under_a_bead(&r.polygon, layer))
}

/// Whether a strand other than sparse infill lays its bead over part of `polygon`: its centre
/// line passes within less than half its width of it (by a micrometre: a bead's edge along
/// the region's edge does not count).
fn under_a_bead(polygon: &Polygon<f64>, layer: &Layer) -> bool {
    use geo::{Distance, Euclidean};
    let Some(bb) = polygon.bounding_rect() else {
        return false;
    };
    layer
        .paths
        .iter()
        .filter(|p| p.role.is_part() && p.role != Role::Infill && p.points.len() >= 2)
        .any(|p| {
            let reach = p.width / 2.0 - 1e-3;
            let grown = Rect::new(
                coord! {x: bb.min().x - reach, y: bb.min().y - reach},
                coord! {x: bb.max().x + reach, y: bb.max().y + reach},
            );
            if !path_box(p).is_some_and(|pb| boxes_meet(&pb, &grown)) {
                return false;
            }
            p.points.windows(2).any(|w| {
                let seg = Line::new(
                    coord! {x: w[0][0], y: w[0][1]},
                    coord! {x: w[1][0], y: w[1][1]},
                );
                Euclidean.distance(&seg, polygon) < reach
            })
        })
}

/// Whether support material is all that prints a region: all the strands inside it, or,
/// when none runs inside (a gap between support lines that the printed area closes), all
/// those within a bead's width of it.
fn support_only(r: &Region, layer: &Layer, boxes: &[Option<Rect<f64>>]) -> bool {
    let support = [Role::Support.name(), Role::SupportInterface.name()];
    let only = |e: &[RoleExtrusion]| !e.is_empty() && e.iter().all(|e| support.contains(&e.role));
    if !r.extrusions.is_empty() {
        return only(&r.extrusions);
    }
    // Nothing near is support where the layer prints none (the search below grows the region
    // and clips every strand of the layer to it).
    if !layer.paths.iter().any(|p| support.contains(&p.role.name())) {
        return false;
    }
    let reach = layer
        .paths
        .iter()
        .map(|p| p.width)
        .fold(0.0, f64::max)
        .min(2.0);
    let grown = super::offset(&MultiPolygon::new(vec![r.polygon.clone()]), reach);
    let near: Vec<RoleExtrusion> = grown
        .0
        .iter()
        .flat_map(|p| extrusions_inside(p, layer, boxes).0)
        .collect();
    only(&near)
}

pub(super) fn boxes_meet(a: &Rect<f64>, b: &Rect<f64>) -> bool {
    super::boxes_within(Some(a), Some(b), 0.0)
}

/// `raw` with its pieces that lie less than `2 r` apart joined into one (a closing by `r`):
/// the slits between a slicer's bridge strands (PrusaSlicer's thick bridges at 0.3 mm layers
/// lie 0.05 mm apart) are no gaps, beads squash into them, as the planner takes them. Cut
/// along every slit, a shelf's bridge over air came apart into 30 strips, each a region,
/// and each planned loops over the whole zone the closed area makes of them: 20 plans over
/// one area, 100 mm of loops for a 5 mm2 strip (+27 % time). Pieces that join nothing are
/// kept as they are.
fn joined_across_slits(raw: MultiPolygon<f64>, r: f64) -> MultiPolygon<f64> {
    use geo::Intersects;
    if raw.0.len() < 2 || r <= 0.0 {
        return raw;
    }
    // Only pieces within `2 r` of another can join; growing by `r` keeps a piece inside its
    // box grown by `r`, so a piece whose grown box meets no other's closes alone and is kept
    // as it is. Those are left out of the closing (a plate's caps: one ring each, far apart,
    // were all grown and shrunk for nothing).
    let near = near_another(&raw, r);
    let (near_pieces, far): (Vec<_>, Vec<_>) = raw.0.into_iter().zip(near).partition(|(_, n)| *n);
    let raw = MultiPolygon::new(near_pieces.into_iter().map(|(p, _)| p).collect());
    let far = far.into_iter().map(|(p, _)| p);
    if raw.0.len() < 2 {
        return MultiPolygon::new(raw.0.into_iter().chain(far).collect());
    }
    let closed = super::closing(&raw, r);
    if closed.0.len() >= raw.0.len() {
        return MultiPolygon::new(raw.0.into_iter().chain(far).collect());
    }
    let mut out = Vec::with_capacity(closed.0.len());
    let mut used = vec![false; raw.0.len()];
    for c in closed.0 {
        let members: Vec<usize> = (0..raw.0.len())
            .filter(|&i| !used[i] && c.intersects(&raw.0[i]))
            .collect();
        match members.as_slice() {
            [] => {}
            [one] => {
                used[*one] = true;
                out.push(raw.0[*one].clone());
            }
            many => {
                for &i in many {
                    used[i] = true;
                }
                out.push(c);
            }
        }
    }
    out.extend(
        raw.0
            .iter()
            .zip(used)
            .filter(|(_, u)| !u)
            .map(|(p, _)| p.clone()),
    );
    out.extend(far);
    MultiPolygon::new(out)
}

/// For each polygon of `mp`, whether its box grown by `r` meets another's (a sweep over the
/// boxes sorted by their left edge). A polygon without a box (an empty ring) is left to the
/// closing to judge, as before.
fn near_another(mp: &MultiPolygon<f64>, r: f64) -> Vec<bool> {
    let mut near = vec![false; mp.0.len()];
    let mut boxes: Vec<(usize, Rect<f64>)> = Vec::with_capacity(mp.0.len());
    for (i, p) in mp.0.iter().enumerate() {
        match p.bounding_rect() {
            Some(b) => boxes.push((i, b)),
            None => near[i] = true,
        }
    }
    boxes.sort_by(|a, b| a.1.min().x.total_cmp(&b.1.min().x));
    for (k, (i, bi)) in boxes.iter().enumerate() {
        for (j, bj) in &boxes[k + 1..] {
            if bj.min().x - r > bi.max().x + r {
                break;
            }
            if bi.min().y - r <= bj.max().y + r && bj.min().y - r <= bi.max().y + r {
                near[*i] = true;
                near[*j] = true;
            }
        }
    }
    near
}

/// `here - (below grown by tol)`, part by part: each polygon of `here` (they are disjoint)
/// minus the growth of the polygons of `below` whose boxes come within `tol` of its box (no
/// other's growth reaches it). On a plate the booleans stay the size of one part, the parts
/// run on all cores, and what no part comes near is never grown.
fn uncovered(here: &MultiPolygon<f64>, below: &MultiPolygon<f64>, tol: f64) -> MultiPolygon<f64> {
    use rayon::prelude::*;
    let index = super::BoxIndex::new(below);
    // Round joins lie on the arc; the margin covers Clipper's integer rounding.
    let m = tol.max(0.0) + 1e-3;
    let parts: Vec<Vec<Polygon<f64>>> = here
        .0
        .par_iter()
        .map(|p| {
            let Some(b) = p.bounding_rect() else {
                return Vec::new();
            };
            // Only what lies within `tol` of the part can grow into it: a polygon below that
            // reaches far past the part's box (support's lines round a stem) is cut to the
            // box grown by a little more first, and its growth inside the part is the same.
            let (lo, hi) = (
                [b.min().x - m, b.min().y - m],
                [b.max().x + m, b.max().y + m],
            );
            let window = Rect::new(
                coord! {x: lo[0] - m, y: lo[1] - m},
                coord! {x: hi[0] + m, y: hi[1] + m},
            )
            .to_polygon();
            let near: Vec<Polygon<f64>> = index
                .meeting(lo, hi)
                .flat_map(|i| {
                    let q = &below.0[i];
                    let inside = q.bounding_rect().is_some_and(|qb| {
                        qb.min().x >= lo[0] - m
                            && qb.min().y >= lo[1] - m
                            && qb.max().x <= hi[0] + m
                            && qb.max().y <= hi[1] + m
                    });
                    if inside || q.exterior().0.len() < 64 {
                        vec![q.clone()]
                    } else {
                        BooleanOps::intersection(q, &window).0
                    }
                })
                .collect();
            if near.is_empty() {
                return vec![p.clone()];
            }
            let grown = offset_parts(&MultiPolygon::new(near), tol);
            if grown.0.is_empty() {
                vec![p.clone()]
            } else {
                BooleanOps::difference(p, &grown).0
            }
        })
        .collect();
    MultiPolygon::new(parts.into_iter().flatten().collect())
}

fn describe(
    polygon: Polygon<f64>,
    below: &MultiPolygon<f64>,
    anchor_reach: f64,
    layer: &Layer,
    boxes: &[Option<Rect<f64>>],
    opts: &DetectOptions,
) -> Region {
    // Anchors shorter than a perimeter width are noise along the boundary, whatever the
    // narrowest region kept.
    let min_stretch = opts.min_width().max(opts.external_width);
    // The anchor zone (the layer below grown by `anchor_reach`) near the region: only the
    // polygons below within that reach of its box can grow into it.
    let anchor_zone = match polygon.bounding_rect() {
        Some(b) => offset_parts(&near(below, &b, anchor_reach + 1e-3), anchor_reach),
        None => MultiPolygon::new(Vec::new()),
    };
    let mut anchors = 0;
    let mut anchored_length = 0.0;
    // The zone's boundary in a grid: every sample along the region's rings asks it (each
    // `contains` walked all of a plate's cap's ring: a third of the region search).
    let zone_index = super::RingIndex::new(&anchor_zone);
    for ring in std::iter::once(polygon.exterior()).chain(polygon.interiors()) {
        let (n, len) = anchored_stretches(ring, &zone_index, min_stretch);
        anchors += n;
        anchored_length += len;
    }
    let reach = max_distance(&polygon, below);
    let kind = match anchors {
        0 => RegionKind::Floating,
        1 => RegionKind::Overhang,
        // A thin ring or strip (a gradual overhang) touches the anchor zone all along, on
        // both of its edges in places: nothing in it spans anything.
        _ if reach <= THIN_REACH * opts.external_width => RegionKind::Overhang,
        // Part of it reaches out past every span between its anchors (a table top's rim
        // beyond its legs): strands there end in air whatever the slicer does, and the
        // whole region is grown from its anchors like an overhang.
        _ if cantilevered(&polygon, &anchor_zone, opts.external_width) => RegionKind::Overhang,
        _ => RegionKind::Bridge,
    };
    let (extrusions, object) = extrusions_inside(&polygon, layer, boxes);
    Region {
        layer: layer.index,
        z: layer.z,
        height: layer.height,
        kind,
        area: polygon.unsigned_area(),
        max_distance: reach,
        anchored_length,
        anchors,
        object,
        extrusions,
        polygon,
    }
}

/// Samples `ring` every [`ANCHOR_STEP`] and returns how many maximal runs of samples lie in
/// `zone` (runs shorter than `min_len` ignored, the ring treated as cyclic) and their length.
fn anchored_stretches(
    ring: &LineString<f64>,
    zone: &super::RingIndex,
    min_len: f64,
) -> (usize, f64) {
    if zone.is_empty() || ring.0.len() < 3 {
        return (0, 0.0);
    }
    // (inside, length of the sample's share of the ring)
    let mut samples: Vec<(bool, f64)> = Vec::new();
    let step = anchor_step([ring]);
    let (mut ts, mut inside) = (Vec::new(), Vec::new());
    for w in ring.0.windows(2) {
        let (a, b) = (w[0], w[1]);
        let len = ((b.x - a.x).powi(2) + (b.y - a.y).powi(2)).sqrt();
        let n = ((len / step).ceil() as usize).max(1);
        ts.clear();
        ts.extend((0..n).map(|k| (k as f64 + 0.5) / n as f64));
        inside.clear();
        zone.contains_strictly_along([a.x, a.y], [b.x, b.y], &ts, &mut inside);
        samples.extend(inside.iter().map(|&i| (i, len / n as f64)));
    }
    if samples.iter().all(|s| s.0) {
        let total: f64 = samples.iter().map(|s| s.1).sum();
        return (1, total);
    }
    // Rotate so that the sequence starts outside the zone: runs then never wrap.
    let start = samples.iter().position(|s| !s.0).unwrap_or(0);
    samples.rotate_left(start);
    let (mut count, mut total, mut run) = (0, 0.0, 0.0);
    for (inside, len) in samples.into_iter().chain(std::iter::once((false, 0.0))) {
        if inside {
            run += len;
        } else if run > 0.0 {
            if run >= min_len {
                count += 1;
                total += run;
            }
            run = 0.0;
        }
    }
    (count, total)
}

/// Whether a region anchored in several places has more than [`CANTILEVER_AREA`] mm2 of it
/// outside the convex hull of its anchored boundary (grown by a bead width `w`, and opened
/// by half a width: slivers along a bridge's sides are its edges, not a cantilever).
fn cantilevered(polygon: &Polygon<f64>, zone: &MultiPolygon<f64>, w: f64) -> bool {
    use geo::ConvexHull;
    let mut anchored: Vec<Point<f64>> = Vec::new();
    let step = anchor_step(std::iter::once(polygon.exterior()).chain(polygon.interiors()));
    for ring in std::iter::once(polygon.exterior()).chain(polygon.interiors()) {
        for seg in ring.0.windows(2) {
            let (a, b) = (seg[0], seg[1]);
            let len = ((b.x - a.x).powi(2) + (b.y - a.y).powi(2)).sqrt();
            let n = ((len / step).ceil() as usize).clamp(1, 100_000);
            for k in 0..=n {
                let t = k as f64 / n as f64;
                let p = Point::new(a.x + (b.x - a.x) * t, a.y + (b.y - a.y) * t);
                if zone.contains(&p) {
                    anchored.push(p);
                }
            }
        }
    }
    if anchored.len() < 3 {
        return false;
    }
    let hull = geo::MultiPoint::new(anchored).convex_hull();
    let spans = super::offset(&MultiPolygon::new(vec![hull]), w);
    let beyond = BooleanOps::difference(polygon, &spans);
    opening(&beyond, w / 2.0).unsigned_area() > CANTILEVER_AREA
}

/// Area (mm2) of a bridge outside the spans between its anchors past which it is an
/// overhang: the default smallest region.
const CANTILEVER_AREA: f64 = 1.0;

/// Largest distance from the region to `below`, sampled at the region's vertices and on a
/// grid inside it.
pub fn max_distance(polygon: &Polygon<f64>, below: &MultiPolygon<f64>) -> f64 {
    let Some(rb) = polygon.bounding_rect() else {
        return 0.0;
    };
    // Any one point of `below` bounds every distance from the region's box; a polygon whose
    // box lies farther than that bound from the region's box cannot hold a nearest point.
    // The point is taken from the polygon whose box is nearest the region's: the first one
    // of a plate's layer lies across the plate, and its bound kept every part (a plate of
    // 625 caps: each cap's distances searched every post's edges, half of `analyze`).
    let box_gap = |q: &Polygon<f64>| {
        q.bounding_rect().map_or(f64::INFINITY, |b| {
            let dx = (b.min().x - rb.max().x)
                .max(rb.min().x - b.max().x)
                .max(0.0);
            let dy = (b.min().y - rb.max().y)
                .max(rb.min().y - b.max().y)
                .max(0.0);
            dx.hypot(dy)
        })
    };
    let Some(v) = below
        .0
        .iter()
        .filter(|q| !q.exterior().0.is_empty())
        .map(|q| (box_gap(q), q))
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .and_then(|(_, q)| q.exterior().0.first())
    else {
        return f64::INFINITY;
    };
    let bound = [
        rb.min(),
        rb.max(),
        coord! {x: rb.min().x, y: rb.max().y},
        coord! {x: rb.max().x, y: rb.min().y},
    ]
    .iter()
    .map(|c| (c.x - v.x).hypot(c.y - v.y))
    .fold(0.0, f64::max);
    let below = near(below, &rb, bound);
    // The region lies outside `below` (it is what is left after taking `below` grown away),
    // so a point's distance to `below` is its distance to the nearest edge of its rings.
    let edges: Vec<Line<f64>> = below
        .0
        .iter()
        .flat_map(|q| std::iter::once(q.exterior()).chain(q.interiors()))
        .flat_map(|r| r.lines())
        .collect();
    if edges.is_empty() {
        return f64::INFINITY;
    }
    let tree = RTree::bulk_load(edges);
    let dist = |p: &Point<f64>| {
        tree.nearest_neighbor_iter_with_distance_2(p)
            .next()
            .map_or(f64::INFINITY, |(_, d2)| d2.sqrt())
    };
    // Which grid points lie in the region, from its boundary in a grid (a point-in-polygon
    // test walks every edge: a gradual cap's ring of thousands, 3600 times).
    let inside = super::RingIndex::new(&MultiPolygon::new(vec![polygon.clone()]));
    let mut best: f64 = 0.0;
    for c in polygon.exterior().0.iter() {
        best = best.max(dist(&Point::from(*c)));
    }
    let b = rb;
    // A coarse grid, then finer grids around the best point so far.
    let mut step = (b.width().max(b.height()) / 30.0).max(0.1);
    let (mut x0, mut y0, mut x1, mut y1) = (b.min().x, b.min().y, b.max().x, b.max().y);
    for _ in 0..4 {
        let mut best_p = None;
        let mut y = y0 + step / 2.0;
        while y < y1 {
            let mut x = x0 + step / 2.0;
            while x < x1 {
                let p = Point::new(x, y);
                if inside.contains_strictly([x, y]) {
                    let d = dist(&p);
                    if d > best {
                        best = d;
                        best_p = Some(p);
                    }
                }
                x += step;
            }
            y += step;
        }
        let Some(p) = best_p else { break };
        (x0, y0, x1, y1) = (p.x() - step, p.y() - step, p.x() + step, p.y() + step);
        step /= 5.0;
    }
    best
}

fn path_box(p: &crate::layers::Path) -> Option<Rect<f64>> {
    super::points_box(&p.points)
}

/// Length and filament of the layer's extrusions inside `polygon`, by role, and the object
/// with the most length inside.
fn extrusions_inside(
    polygon: &Polygon<f64>,
    layer: &Layer,
    boxes: &[Option<Rect<f64>>],
) -> (Vec<RoleExtrusion>, Option<u32>) {
    let Some(bb) = polygon.bounding_rect() else {
        return (Vec::new(), None);
    };
    // One index of the region's boundary for all the strands near it: clipping each strand
    // by the polygon set up an overlay per strand (4 % of a plate's rewrite).
    let region = super::RingIndex::new(&MultiPolygon::new(vec![polygon.clone()]));
    let mut by_role: Vec<(Role, f64, f64)> = Vec::new();
    let mut by_object: Vec<(Option<u32>, f64)> = Vec::new();
    for (p, pb) in layer.paths.iter().zip(boxes) {
        let meets = pb.is_some_and(|pb| {
            pb.min().x <= bb.max().x
                && pb.max().x >= bb.min().x
                && pb.min().y <= bb.max().y
                && pb.max().y >= bb.min().y
        });
        if !meets || p.points.len() < 2 {
            continue;
        }
        let len: f64 = region
            .inside_intervals(&p.points)
            .iter()
            .map(|(a, b)| b - a)
            .sum();
        if len <= 1e-9 {
            continue;
        }
        let total = p.length();
        let e = if total > 0.0 {
            p.e() * len / total
        } else {
            0.0
        };
        match by_role.iter_mut().find(|r| r.0 == p.role) {
            Some(r) => {
                r.1 += len;
                r.2 += e;
            }
            None => by_role.push((p.role, len, e)),
        }
        match by_object.iter_mut().find(|o| o.0 == p.object) {
            Some(o) => o.1 += len,
            None => by_object.push((p.object, len)),
        }
    }
    by_role.sort_by_key(|r| r.0);
    let object = by_object
        .into_iter()
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .and_then(|o| o.0);
    (
        by_role
            .into_iter()
            .map(|(role, length_mm, filament_mm)| RoleExtrusion {
                role: role.name(),
                length_mm,
                filament_mm,
            })
            .collect(),
        object,
    )
}

#[cfg(test)]
mod tests {
    use super::super::testutil::*;
    use super::*;

    #[test]
    fn a_bridge_with_a_rim_past_its_anchors_is_cantilevered() {
        let rect = |x0: f64, y0: f64, x1: f64, y1: f64| {
            Polygon::new(
                LineString::from(vec![(x0, y0), (x1, y0), (x1, y1), (x0, y1), (x0, y0)]),
                vec![],
            )
        };
        // Two piers under the ends of a 40 mm span, 10 mm wide (grown by the anchor reach).
        let piers = MultiPolygon::new(vec![
            rect(-5.0, -0.3, 0.3, 10.3),
            rect(39.7, -0.3, 45.0, 10.3),
        ]);
        // The deck between them: every part lies between its anchors.
        assert!(!cantilevered(&rect(0.0, 0.0, 40.0, 10.0), &piers, 0.45));
        // A deck 4 mm wider than the piers on one side: its rim has nothing to span to.
        assert!(cantilevered(&rect(0.0, 0.0, 40.0, 14.0), &piers, 0.45));
        // A sliver along the side (half a bead) is the deck's edge, not a rim.
        assert!(!cantilevered(&rect(0.0, 0.0, 40.0, 10.6), &piers, 0.45));
    }
    use crate::layers::LayerKind;
    use geo::{coord, LineString};

    #[test]
    fn strips_a_slit_apart_are_one_region_and_others_stay_as_they_are() {
        // A bridge's strands 0.4 mm wide laid 0.45 mm apart: strips over air with 0.05 mm
        // slits between them, and a separate piece 2 mm off.
        let strips: Vec<Polygon<f64>> = (0..6)
            .map(|i| {
                let x = f64::from(i) * 0.45;
                rect(x, 0.0, x + 0.4, 10.0)
            })
            .chain(std::iter::once(rect(4.6, 0.0, 6.0, 10.0)))
            .collect();
        let raw = mp(strips.clone());
        let joined = joined_across_slits(raw.clone(), 0.45 / 4.0);
        assert_eq!(joined.0.len(), 2, "the strips join, the far piece does not");
        // The joined strips cover their span, slits included, and no more.
        let span = joined
            .0
            .iter()
            .find(|p| p.contains(&Point::new(1.0, 5.0)))
            .expect("the joined strips");
        assert!((span.unsigned_area() - 2.65 * 10.0).abs() < 0.05);
        // The far piece is kept exactly as it was.
        assert!(joined.0.contains(&strips[6]));
        // Pieces far apart are returned untouched.
        let apart = mp(vec![rect(0.0, 0.0, 1.0, 1.0), rect(3.0, 0.0, 4.0, 1.0)]);
        assert_eq!(joined_across_slits(apart.clone(), 0.1125), apart);
    }

    #[test]
    fn only_pieces_within_reach_of_another_are_closed() {
        // Boxes 0.2 apart in X (within 2 r = 0.225), one 0.3 apart in Y from the first (not),
        // one far off; one inside the hole of a frame.
        let frame = Polygon::new(
            LineString::from(vec![(20.0, 0.0), (30.0, 0.0), (30.0, 10.0), (20.0, 10.0)]),
            vec![LineString::from(vec![
                (21.0, 1.0),
                (29.0, 1.0),
                (29.0, 9.0),
                (21.0, 9.0),
            ])],
        );
        let pieces = mp(vec![
            rect(0.0, 0.0, 1.0, 1.0),
            rect(1.2, 0.0, 2.0, 1.0),
            rect(0.0, 1.3, 1.0, 2.0),
            rect(10.0, 10.0, 11.0, 11.0),
            frame,
            rect(24.0, 4.0, 26.0, 6.0),
        ]);
        assert_eq!(
            near_another(&pieces, 0.1125),
            [true, true, false, false, true, true]
        );
        // The two within reach join; the rest come back as they were.
        let joined = joined_across_slits(pieces.clone(), 0.1125);
        assert_eq!(joined.0.len(), 5);
        for kept in [2, 3, 4, 5] {
            assert!(
                joined.0.contains(&pieces.0[kept]),
                "piece {kept} kept as it was"
            );
        }
        let both = joined
            .0
            .iter()
            .find(|p| p.contains(&Point::new(1.1, 0.5)))
            .expect("the two pieces joined across their gap");
        assert!(
            (both.unsigned_area() - 2.0).abs() < 0.03,
            "{}",
            both.unsigned_area()
        );
    }

    #[test]
    fn uncovered_part_by_part_is_the_whole_difference() {
        // Three parts: one fully covered, one half covered, one with nothing near it; the
        // cover also has a polygon far from every part.
        let here = mp(vec![
            rect(0.0, 0.0, 10.0, 10.0),
            rect(20.0, 0.0, 30.0, 10.0),
            rect(40.0, 0.0, 50.0, 10.0),
        ]);
        let cover = mp(vec![
            rect(-1.0, -1.0, 11.0, 11.0),
            rect(19.0, -1.0, 25.0, 11.0),
            rect(100.0, 100.0, 110.0, 110.0),
        ]);
        let parts = uncovered(&here, &cover, 0.0);
        let whole = BooleanOps::difference(&here, &cover);
        assert!(
            (parts.unsigned_area() - 150.0).abs() < 1e-6,
            "{}",
            parts.unsigned_area()
        );
        assert!((parts.unsigned_area() - whole.unsigned_area()).abs() < 1e-6);
        assert_eq!(parts.0.len(), 2);
        // Grown by 0.5 mm the cover takes 0.5 mm more off the half-covered part, and the far
        // polygon is never grown into anything.
        let grown = uncovered(&here, &cover, 0.5);
        let whole = BooleanOps::difference(&here, &crate::geometry::offset(&cover, 0.5));
        assert!((grown.unsigned_area() - whole.unsigned_area()).abs() < 1e-3);
        assert!(
            (grown.unsigned_area() - 145.0).abs() < 1e-3,
            "{}",
            grown.unsigned_area()
        );
    }

    fn layer() -> Layer {
        Layer {
            kind: LayerKind::Layer,
            index: 5,
            marker_number: None,
            z: 1.2,
            height: 0.2,
            rests_on: vec![4],
            walls_on_previous: true,
            contact: Vec::new(),
            gap_below: Vec::new(),
            helical: false,
            spread: 0.0,
            paths: Vec::new(),
            first_line: 1,
            last_line: 1,
            raw: Vec::new(),
            start: None,
            objects: None,
        }
    }

    fn regions(below: Vec<Polygon<f64>>, here: Vec<Polygon<f64>>) -> Vec<Region> {
        find_regions(&mp(below), &layer(), &mp(here), &DetectOptions::default())
    }

    fn circle(cx: f64, cy: f64, r: f64) -> LineString<f64> {
        let n = 180;
        LineString::new(
            (0..=n)
                .map(|i| {
                    let a = std::f64::consts::TAU * (i % n) as f64 / n as f64;
                    coord! {x: cx + r * a.cos(), y: cy + r * a.sin()}
                })
                .collect(),
        )
    }

    #[test]
    fn every_cap_of_a_plate_of_like_caps_reaches_as_far_from_its_post() {
        // 25 x 25 posts 1.6 mm across, 6 mm apart, under caps 4.5 mm across: each cap's ring
        // reaches (4.5 - 1.6) / 2 from its post, give or take the circles' facets. R-tree
        // `nearest_neighbor` over edges pruned the true nearest edge now and then: 45 of the
        // 625 caps of such a plate by PrusaSlicer reached 1.6-4.3 mm (and the bound taken
        // from the layer's first post searched every post's edges for every cap).
        let posts: Vec<Polygon<f64>> = (0..625)
            .map(|k| {
                let (x, y) = (6.0 * (k % 25) as f64, 6.0 * (k / 25) as f64);
                Polygon::new(circle(x, y, 0.8), vec![])
            })
            .collect();
        let below = mp(posts);
        for k in 0..625 {
            let (x, y) = (6.0 * (k % 25) as f64, 6.0 * (k / 25) as f64);
            let ring = Polygon::new(circle(x, y, 2.25), vec![circle(x, y, 0.8)]);
            let d = max_distance(&ring, &below);
            assert!((d - 1.45).abs() < 0.01, "cap {k} reaches {d:.3} mm");
        }
    }

    #[test]
    fn span_anchored_on_two_sides_is_a_bridge() {
        let r = regions(
            vec![rect(0.0, 0.0, 10.0, 20.0), rect(50.0, 0.0, 60.0, 20.0)],
            vec![rect(0.0, 0.0, 60.0, 20.0)],
        );
        assert_eq!(r.len(), 1);
        assert_eq!(r[0].kind, RegionKind::Bridge);
        assert_eq!(r[0].anchors, 2);
        let expected = (40.0 - 2.0 * 0.225) * 20.0;
        assert!(
            (r[0].area - expected).abs() / expected < 0.01,
            "{}",
            r[0].area
        );
        assert!(
            (r[0].anchored_length - 40.0).abs() < 1.0,
            "{}",
            r[0].anchored_length
        );
        assert!(
            (r[0].max_distance - 20.0).abs() < 0.5,
            "{}",
            r[0].max_distance
        );
    }

    #[test]
    fn cantilever_is_an_overhang() {
        let r = regions(
            vec![rect(0.0, 0.0, 10.0, 20.0)],
            vec![rect(0.0, 0.0, 50.0, 20.0)],
        );
        assert_eq!(r.len(), 1);
        assert_eq!(r[0].kind, RegionKind::Overhang);
        assert!((r[0].area - 39.775 * 20.0).abs() < 2.0);
        assert!(
            (r[0].max_distance - (40.0f64.powi(2) + 20.0f64.powi(2)).sqrt()).abs() < 0.5
                || (r[0].max_distance - 40.0).abs() < 0.5
        );
    }

    #[test]
    fn ring_around_a_stem_is_one_overhang_with_a_hole() {
        let stem = Polygon::new(circle(0.0, 0.0, 5.0), Vec::new());
        let disc = Polygon::new(circle(0.0, 0.0, 15.0), Vec::new());
        let r = regions(vec![stem], vec![disc]);
        assert_eq!(r.len(), 1);
        assert_eq!(r[0].kind, RegionKind::Overhang);
        assert_eq!(r[0].polygon.interiors().len(), 1);
        let expected = std::f64::consts::PI * (15.0f64.powi(2) - 5.225f64.powi(2));
        assert!((r[0].area - expected).abs() / expected < 0.01);
    }

    #[test]
    fn two_disjoint_regions() {
        let r = regions(
            vec![rect(0.0, 0.0, 10.0, 10.0), rect(40.0, 0.0, 50.0, 10.0)],
            vec![rect(0.0, 0.0, 20.0, 10.0), rect(40.0, 0.0, 50.0, 25.0)],
        );
        assert_eq!(r.len(), 2);
        assert!(r.iter().all(|r| r.kind == RegionKind::Overhang));
    }

    #[test]
    fn slope_of_45_degrees_gives_no_region() {
        // Each 0.2 mm layer sticks out 0.2 mm: within the 0.225 mm tolerance.
        let r = regions(
            vec![rect(0.0, 0.0, 10.0, 10.0)],
            vec![rect(0.0, 0.0, 10.2, 10.0)],
        );
        assert!(r.is_empty());
    }

    #[test]
    fn slope_of_70_degrees_is_a_thin_overhang() {
        let step = 0.2 * 70f64.to_radians().tan();
        let below = vec![rect(0.0, 0.0, 10.0, 20.0)];
        let here = vec![rect(0.0, 0.0, 10.0 + step, 20.0)];
        // One perimeter width as the minimum width (the old default) drops it ...
        let wide_only = DetectOptions {
            min_width: Some(0.45),
            ..Default::default()
        };
        assert!(
            find_regions(&mp(below.clone()), &layer(), &mp(here.clone()), &wide_only).is_empty()
        );
        // ... the default keeps the gradual overhang's strip, as a thin overhang.
        let opts = DetectOptions::default();
        let r = find_regions(&mp(below), &layer(), &mp(here), &opts);
        assert_eq!(r.len(), 1);
        assert!(
            (r[0].area - (step - 0.225) * 20.0).abs() < 0.3,
            "{}",
            r[0].area
        );
    }

    #[test]
    fn a_cavity_closing_in_by_less_than_a_bead_is_held_where_its_wall_hangs() {
        // A dome shell's inside: the layer below walls a round cavity of radius 10; this
        // layer's inner wall steps in 0.35 mm (63 degrees at 0.2 mm layers). The strip past
        // the tolerance lies in the hole below and no strand's centre line enters it: it is
        // the outer half of the inner wall's bead.
        let ring = |hole: f64| Polygon::new(circle(0.0, 0.0, 20.0), vec![circle(0.0, 0.0, hole)]);
        let (below, here) = (mp(vec![ring(10.0)]), mp(vec![ring(9.65)]));
        let centre = 9.65 + 0.225;
        let wall: Vec<[f64; 2]> = (0..=180)
            .map(|i| {
                let a = std::f64::consts::TAU * (i % 180) as f64 / 180.0;
                [centre * a.cos(), centre * a.sin()]
            })
            .collect();
        let walled = crate::layers::testing::layer(
            5,
            vec![crate::layers::testing::path(
                Role::ExternalPerimeter,
                0.45,
                &wall,
            )],
        );
        let opts = DetectOptions::default();
        let r = find_regions_as_sliced(&below, &walled, &here, &opts);
        assert_eq!(r.len(), 1, "{r:?}");
        assert_eq!(r[0].kind, RegionKind::Overhang);
        let expected = std::f64::consts::PI * (9.775f64.powi(2) - 9.65f64.powi(2));
        assert!(
            (r[0].area - expected).abs() < 0.1 * expected,
            "{}",
            r[0].area
        );
        // The same hole closed in the printed area with nothing printed there is the
        // part's inside, as before.
        let bare = crate::layers::testing::layer(5, Vec::new());
        assert!(find_regions_as_sliced(&below, &bare, &here, &opts).is_empty());
        // Sparse infill alongside is no wall.
        let infill = crate::layers::testing::layer(
            5,
            vec![crate::layers::testing::path(Role::Infill, 0.45, &wall)],
        );
        assert!(find_regions_as_sliced(&below, &infill, &here, &opts).is_empty());
    }

    #[test]
    fn angle_tolerance() {
        let opts = DetectOptions {
            tolerance: Tolerance::Angle(45.0),
            ..Default::default()
        };
        assert!((opts.tolerance_at(0.2) - 0.2).abs() < 1e-9);
    }

    #[test]
    fn fuzzy_skin_widens_only_the_automatic_tolerance() {
        let fuzzy = DetectOptions {
            fuzzy_skin: 0.3,
            ..Default::default()
        };
        assert!((fuzzy.tolerance_at(0.2) - (0.225 + 0.3)).abs() < 1e-9);
        let given = DetectOptions {
            tolerance: Tolerance::Distance(0.2),
            ..fuzzy.clone()
        };
        assert!((given.tolerance_at(0.2) - 0.2).abs() < 1e-9);
        // A wall whose perimeter stands 0.4 mm out of the one below (fuzz, one point here
        // out and the point below in) is an overhang without fuzzy skin, not with it.
        let below = vec![rect(0.0, 0.0, 10.0, 10.0)];
        let here = vec![rect(0.0, 0.0, 10.4, 10.0)];
        let plain = DetectOptions::default();
        assert!(!find_regions(&mp(below.clone()), &layer(), &mp(here.clone()), &plain).is_empty());
        assert!(find_regions(&mp(below), &layer(), &mp(here), &fuzzy).is_empty());
    }

    #[test]
    fn floating_island() {
        let r = regions(
            vec![rect(0.0, 0.0, 10.0, 10.0)],
            vec![rect(30.0, 0.0, 40.0, 10.0)],
        );
        assert_eq!(r.len(), 1);
        assert_eq!(r[0].kind, RegionKind::Floating);
    }
}
