//! Stage 5: plan Print-on-Air loops for an unsupported region.
//!
//! Input: a [`Region`] of layer i, the printed area of layer i-1 (sectA) and of layer i
//! (sectB), and the [`PoaSettings`]. Output: a [`Plan`]: the zone whose original extrusions are
//! taken out, and the strands that replace them, in print order:
//! 1. loops: fronts at `k x step - w/2` from sectA (k = 1, 2, ...; step = (1 - overlap) x w),
//!    measured inside the zone (a front wraps around a hole rather than jumping it), so that
//!    loop 1 bites `overlap x w` into the wall below and each loop bites as much into the
//!    previous one; clipped to the zone minus the band of its external perimeter;
//! 2. one contour along the loops' outer clip edge, so the perimeter has material beside it;
//! 3. the external perimeter of the zone, pulled inward by `perimeter_inset`, convex corners
//!    rounded.
//!
//! Invariants: every strand lies inside the zone; each strand's start is chosen near where the
//! previous one ended. Fronts are grown with Clipper and cut back to the zone at every step,
//! which keeps their vertex count bounded by the zone's.

use geo::{Area, MultiPolygon};
use serde::Serialize;

mod copies;
pub use copies::{copy_sources, plan_all, Sources};

use crate::geometry::{
    clip_lines, closing, difference, grow_within, intersection, margin, near, offset, opening,
    rings, union, Polyline, Region, RegionKind,
};

/// What to do with regions anchored on two or more sides.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum BridgeMode {
    /// Leave a bridge as the slicer made it where its strands hold (anchored at both ends
    /// within the deposition check's longest bridge), rewrite it where more than 1 mm of
    /// them would be in air (spans too long, strands along a gap instead of across it).
    Auto,
    /// Leave bridges as the slicer made them (a bridge anchored at both ends prints well).
    Keep,
    /// Rewrite bridges with loops too.
    Poa,
}

/// Settings of the rewrite. Speeds in mm/s, distances in mm. `Default` is implemented where the
/// settings table lives ([`crate::settings`]).
#[derive(Debug, Clone, Serialize)]
pub struct PoaSettings {
    /// Share of a bead's width each loop overlaps the previous one. Defaults of every field
    /// come from the settings table (`crate::settings::SPECS`), the one place they are written.
    pub overlap: f64,
    /// Loop speed; `None` uses the file's bridge speed.
    pub loop_speed: Option<f64>,
    /// Speed of the moved external perimeter; `None` uses the loop speed.
    pub perimeter_speed: Option<f64>,
    /// Part-cooling fan during loops, 0..1.
    pub fan: f64,
    /// Pause after each loop, seconds.
    pub dwell: f64,
    /// Shortest time a loop takes, seconds (shorter loops are slowed).
    pub min_loop_time: f64,
    /// Slowest speed a loop is slowed to for its minimum time; `None` uses the file's minimum
    /// print speed for cooling (not under 5 mm/s).
    pub min_loop_speed: Option<f64>,
    /// Multiplier on the flow-model extrusion of every strand poa writes.
    pub flow_factor: f64,
    /// How far the region's external perimeter is pulled inward.
    pub perimeter_inset: f64,
    /// Nozzle temperature change while printing the loops (degrees C), restored afterwards.
    pub temperature_offset: f64,
    pub bridges: BridgeMode,
}

impl PoaSettings {
    /// Whether a region of this kind gets rewritten.
    pub fn rewrites(&self, kind: RegionKind) -> bool {
        match kind {
            RegionKind::Overhang => true,
            RegionKind::Bridge => self.bridges == BridgeMode::Poa,
            // Nothing to grow loops from.
            RegionKind::Floating => false,
        }
    }
}

/// Widths of the layer being rewritten.
#[derive(Debug, Clone, Copy)]
pub struct Widths {
    /// Loops and contour.
    pub loop_width: f64,
    /// External perimeter.
    pub perimeter_width: f64,
    /// Region detection tolerance (distance from sectA that still counted as supported).
    pub tolerance: f64,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum StrandKind {
    Loop,
    Contour,
    Perimeter,
}

/// One strand poa writes.
#[derive(Debug, Clone)]
pub struct Strand {
    pub kind: StrandKind,
    /// 1-based loop number for loops, 0 otherwise.
    pub loop_index: usize,
    pub points: Polyline,
    pub width: f64,
}

impl Strand {
    pub fn length(&self) -> f64 {
        polyline_length(&self.points)
    }
}

/// The rewrite of one region.
#[derive(Debug, Clone)]
pub struct Plan {
    /// Where the original extrusions are taken out.
    pub zone: MultiPolygon<f64>,
    /// Replacement strands in print order.
    pub strands: Vec<Strand>,
    pub loops: usize,
    /// A gradual overhang's plan (a perimeter and at most one loop): printed where the
    /// slicer printed the external perimeter it replaces, after the layer's inner
    /// perimeters, which hold it up as they held the slicer's.
    pub with_perimeter: bool,
    /// A narrow cantilever's plan ([`ladder`]): rungs across the strip the slicer printed as
    /// a loop out and back; they fill that strip, as a wide region's loops fill its zone.
    pub ladder: bool,
}

pub use crate::geometry::polyline_length;

/// Largest distance (mm) by which the planner's windows of the layers (and a zone's outline,
/// before it is opened) are simplified.
const ZONE_SIMPLIFY: f64 = 0.002;

/// Zones narrower than this are slivers of numeric noise along walls, not overhang.
const SLIVER: f64 = 0.03;
/// In a gradual overhang's thin ring, a loop whose centre lies this many widths or more
/// inside the perimeter's is of full width; nearer, of half width.
const HALF_LOOP_AT: f64 = 0.35;
/// ... and a loop is laid only where its centre lies this many widths or more inside the
/// perimeter's: loop 1 (a tenth of a width past the wall below) where the perimeter would
/// hang a quarter width past what holds it, the deposition check's mark. (At 0.3 w, a
/// perimeter between the two was left on 70 % of its width; with one wall, or the outer
/// wall first, nothing else holds it: a headphone hook's arm by Cura with one wall, 50.9 mm
/// in air on one layer. Over 254 held-out slices: 5661 -> 5442 mm in air, time +0.05 %.)
const NEAR_LOOP_AT: f64 = 0.15;
/// A thin ring's loop whose pieces past [`NEAR_LOOP_AT`] make up this share of what lies
/// under the perimeter is laid all along there, [`UNDER_AT`] widths or more inside the
/// perimeter's centre.
const RING_NEEDED: f64 = 0.5;
const UNDER_AT: f64 = 0.05;
/// Shortest stretch (mm) of a half-width ring lying [`HALF_LOOP_AT`] inside the perimeter
/// that gets the full loop there instead: longer than the in-and-out of a faceted wall's
/// ring round the mark, shorter than a face of its own slope.
const MIXED_RUN: f64 = 5.0;
/// Width (in loop widths) of the band round those full stretches where the half loop is
/// left out: the half bead's end (a quarter width) meets the full one's (a half).
const MIXED_MASK: f64 = 1.5;
/// How much nearer the loop before (in widths) a half-width loop of a thin ring lies than a
/// full one: at a full step its narrower bead would only just touch the loop before.
const HALF_BACK: f64 = 0.05;

/// Most loop vertices one region's plan may hold (~32 MB): a region kilometres across (a
/// file whose moves went relative by a stray G91) would otherwise grow hundreds of
/// thousands of fronts and exhaust memory. No region of a real print comes near: a 200 mm
/// disc at 0.27 mm steps is some 370 loops of a few thousand points.
const PLAN_POINTS: usize = 2_000_000;

/// No plan: nothing of the region is rewritten.
fn no_plan(zone: MultiPolygon<f64>) -> Plan {
    Plan {
        zone,
        strands: Vec::new(),
        loops: 0,
        with_perimeter: false,
        ladder: false,
    }
}

fn points_of(pieces: &[Polyline]) -> usize {
    pieces.iter().map(Vec::len).sum()
}

/// The layer's other regions, as they bear on one region's plan.
#[derive(Debug, Clone)]
pub struct Others {
    /// What the plan must leave as sliced: the layer's regions not rewritten (a floating
    /// ring of walls round a slot kept its strands only if no zone reached over it).
    pub keep_out: MultiPolygon<f64>,
    /// Floating regions next to this one, planned with it: its loops grow into them (the
    /// walls round a slot in an overhang, which Cura prints apart when the outer wall goes
    /// first, were left floating and the layer above hung over the slot).
    pub absorb: MultiPolygon<f64>,
    /// Where the layer above prints past this layer's outline near the region and is kept
    /// as sliced (its bridges over a gap this layer leaves, its floating parts): the outline
    /// there is not the part's surface but what the layer above was sliced to stand on, so
    /// the perimeter under it stays where the slicer put it (not pulled in by the inset).
    pub overhung: MultiPolygon<f64>,
}

impl Default for Others {
    fn default() -> Self {
        Others {
            keep_out: MultiPolygon::new(Vec::new()),
            absorb: MultiPolygon::new(Vec::new()),
            overhung: MultiPolygon::new(Vec::new()),
        }
    }
}

/// What [`plan`] reads of the layer below and of the layer near a region: a margin round the
/// region (and the regions it absorbs), and the two areas cut to boxes round it and
/// simplified by 2 um (the layer's before its closing). Everything the planner knows of
/// `below` and `area` comes from these.
pub(super) struct Windows {
    /// The region and the floating regions it absorbs.
    pub region: MultiPolygon<f64>,
    pub hint: MultiPolygon<f64>,
    pub below: MultiPolygon<f64>,
    pub area: MultiPolygon<f64>,
}

pub(super) fn windows(
    region: &Region,
    below: &MultiPolygon<f64>,
    area: &MultiPolygon<f64>,
    others: &Others,
    widths: &Widths,
) -> Option<Windows> {
    let w = widths.loop_width;
    let we = widths.perimeter_width;
    let reach = region.max_distance.min(1000.0) + widths.tolerance + 2.0 * w;
    // Work near the region only: sectA within reach of it (every loop point's nearest sectA
    // point lies there), sectB a little beyond it.
    let region_mp = MultiPolygon::new(
        std::iter::once(region.polygon.clone())
            .chain(others.absorb.0.iter().cloned())
            .collect(),
    );
    // A window round the region (a margin: the outline of a gradual overhang's thin ring
    // carries thousands of arc points, which cost more to grow than the rest of its plan).
    let hint = margin(&region_mp, widths.tolerance + w);
    // Booleans with a whole plate's layer cost as much as the plate: take the parts near by.
    // Cut to boxes round the region, not to its offsets: an offset by the region's reach
    // (12 mm on a mushroom's cap) makes thousands of arc points for a boolean to chew, and
    // nothing past the reach takes part (the fronts are cut to near the zone, the zone to
    // `hint`).
    let hint_box = geo::BoundingRect::bounding_rect(&hint)?;
    // The planner's inputs are simplified by 2 um too, for the same reason as the zone below
    // (four spheres on stems: 1.3 -> 0.5 s).
    let below_loc = geo::Simplify::simplify(
        &intersection(
            &near(below, &hint_box, reach + w),
            &boxed(&hint_box, reach + w),
        ),
        ZONE_SIMPLIFY,
    );
    let area_cut = geo::Simplify::simplify(
        &intersection(
            &near(area, &hint_box, 2.0 * we + 2.0),
            &boxed(&hint_box, 2.0 * we + 2.0),
        ),
        ZONE_SIMPLIFY,
    );
    Some(Windows {
        region: region_mp,
        hint,
        below: below_loc,
        area: area_cut,
    })
}

/// Plans the loops of `region` (with the floating regions `others` gives it). `start` is
/// where the nozzle is when the plan begins.
pub fn plan(
    region: &Region,
    below: &MultiPolygon<f64>,
    area: &MultiPolygon<f64>,
    others: &Others,
    widths: Widths,
    settings: &PoaSettings,
    start: [f64; 2],
) -> Plan {
    match windows(region, below, area, others, &widths) {
        Some(win) => plan_in(region, &win, others, widths, settings, start),
        None => no_plan(MultiPolygon::new(Vec::new())),
    }
}

/// `area` without its holes smaller than a bead (under `w` x `w` in area, and no more than
/// two beads across): the gaps the slicer's walls leave where they meet (a wheel's spoke
/// running into its rim: 0.3 mm holes either side of the spoke's end). No part has a hole a
/// bead cannot print round; grown by the contour's inset, such a gap cut the loop area
/// through at the joint, and the fronts crossed it printing nothing for four steps, so the
/// rim's first loops there hung (1.8 mm in air at each of six joints).
fn without_specks(area: MultiPolygon<f64>, w: f64) -> MultiPolygon<f64> {
    use geo::BoundingRect;
    let speck = |r: &geo::LineString<f64>| {
        geo::Polygon::new(r.clone(), Vec::new()).unsigned_area() < w * w
            && r.bounding_rect()
                .is_some_and(|b| b.width().max(b.height()) <= 2.0 * w)
    };
    if !area.0.iter().any(|p| p.interiors().iter().any(speck)) {
        return area;
    }
    MultiPolygon::new(
        area.0
            .into_iter()
            .map(|p| {
                let (ext, holes) = p.into_inner();
                geo::Polygon::new(ext, holes.into_iter().filter(|h| !speck(h)).collect())
            })
            .collect(),
    )
}

/// `area` with its notches by the layer below's edge filled: the gaps narrower than one and
/// a half widths that lie mostly within a width of what the layer below printed. A hollow
/// part's roof at 0.25 mm layers (PrusaSlicer) is bridge lines at 45 degrees to the wall,
/// turning in pairs 0.3 mm clear of its inner perimeter: V notches 0.4 mm deep line the wall
/// below's edge, loops 1 and 2 lay in them and found no room, and the first loop laid hung
/// 0.58 mm past the wall (95.8 mm in air on the roof's first layer). Filled, the notches are
/// printed by the first loops, from the wall. Gaps away from the layer below (a slot across
/// a hole's ceiling, a clearance between two parts over air) stay open.
fn notches_filled(area: MultiPolygon<f64>, below: &MultiPolygon<f64>, w: f64) -> MultiPolygon<f64> {
    let added = difference(&closing(&area, 0.75 * w), &area);
    if added.0.is_empty() {
        return area;
    }
    let near = offset(below, w);
    let near_share = crate::geometry::shares_within(&added, &near);
    let kept: Vec<geo::Polygon<f64>> = added
        .0
        .into_iter()
        .zip(near_share)
        .filter(|(p, near)| {
            let a = p.unsigned_area();
            a > 0.0 && *near >= 0.5 * a
        })
        .map(|(p, _)| p)
        .collect();
    if kept.is_empty() {
        return area;
    }
    union(&area, &MultiPolygon::new(kept))
}

/// [`plan`] from the [`windows`] made for `region` already.
pub(super) fn plan_in(
    region: &Region,
    win: &Windows,
    others: &Others,
    widths: Widths,
    settings: &PoaSettings,
    start: [f64; 2],
) -> Plan {
    let w = widths.loop_width;
    let we = widths.perimeter_width;
    let overlap = settings.overlap.clamp(0.05, 0.9);
    let step = (1.0 - overlap) * w;
    let inset = settings.perimeter_inset.max(0.0);
    let reach = region.max_distance.min(1000.0) + widths.tolerance + 2.0 * w;
    let (hint, below_loc, area_cut) = (&win.hint, &win.below, &win.area);
    // Gaps narrower than half a bead in what the layer prints are no gaps (beads squash
    // into them): closed, so that an island of walls the slicer set 0.07 mm off the skin (a
    // slot's walls by Cura, outer wall first) is part of the outline the perimeter follows.
    let area_loc = without_specks(closing(area_cut, w / 4.0), w);
    let area_loc = notches_filled(area_loc, below_loc, w);

    // The zone: what sectB prints beyond sectA around this region, slivers dropped.
    // Simplified by 2 um before the opening: the booleans leave thousands of points on a
    // thin ring (a bowl's: 945 -> 176 points), which every later step pays for; the opening
    // alone took 1.9 ms there, 0.3 ms after, and the zone moves by under a micrometre on
    // average.
    let mut zone = opening(
        &geo::Simplify::simplify(
            &intersection(&difference(&area_loc, &offset(below_loc, 0.01)), hint),
            ZONE_SIMPLIFY,
        ),
        SLIVER,
    );
    if !others.keep_out.0.is_empty() {
        zone = difference(&zone, &offset(&others.keep_out, 0.01));
    }
    // Pieces of the zone that do not touch the region are another region's, or lie within
    // the tolerance of the layer below all over: the two sides of a slot closing over a
    // bolt hole, half a millimetre apart, each planned the other's side too, and each side's
    // perimeter was laid twice, once in air before that side's loop.
    {
        use geo::Intersects;
        zone.0
            .retain(|p| win.region.0.iter().any(|r| p.intersects(r)));
    }
    if zone.unsigned_area() <= 0.0 {
        return no_plan(zone);
    }

    // Loops stay inside the contour; contour and perimeter overlap like loops do.
    let contour_at = we / 2.0 + inset + (we + w) / 2.0 - overlap * w;
    let inner = intersection(&zone, &offset(&area_loc, -contour_at));
    // A thin ring of a gradual overhang (each layer a little wider than the one below) has
    // no room for a contour and loops of full width: the perimeter stays where the slicer put
    // it (less the inset, and at most an eighth of a width more: the layer above was sliced
    // on this outline), and where it would hang a quarter width or more beyond loop 1's
    // place, one loop of half width is laid there first, biting into the layer below, so
    // that the perimeter leans on it.
    // (The opening is empty exactly when the erosion is: growing it back adds nothing.)
    // Specks of room smaller than a bead's square hold no loop: the notch a moved perimeter
    // of the layer below leaves where its pieces meet the slicer's (a bowl's flank by Cura,
    // one wall: one speck made the whole ring wide, its perimeter stayed where the slicer
    // put it and hung 0.375 mm past the moved one below, 63.5 mm in air).
    let thin = offset(&inner, -w / 4.0)
        .0
        .iter()
        .all(|p| p.unsigned_area() < w * w);

    // The moved external perimeter: the outline pulled in by half its width plus the inset,
    // convex corners rounded by half a width.
    let round = we / 2.0;
    let mut perimeter_area = offset(&offset(&area_loc, -(we / 2.0 + inset + round)), round);
    // Features the rounding erases whole are kept, sharp as the slicer drew them: a gear's
    // teeth narrower than two perimeters (0.8 mm nozzle, 1.6 mm teeth) were left out of the
    // layer, and the layer above bridged every tooth (1 -> 38 mm bridged). A corner's trim
    // lies within a width of the rounded outline; a feature reaches farther.
    let sharp = offset(&area_loc, -(we / 2.0 + inset));
    let lost = difference(&sharp, &perimeter_area);
    if lost.unsigned_area() > 0.0 {
        let far = difference(&lost, &offset(&perimeter_area, we));
        if !far.0.is_empty() {
            use geo::Intersects;
            let features: Vec<geo::Polygon<f64>> = lost
                .0
                .into_iter()
                .filter(|p| far.0.iter().any(|f| p.intersects(f)))
                .collect();
            perimeter_area = union(&perimeter_area, &MultiPolygon::new(features));
        }
    }
    // Where loop 1's centre goes: the layer below grown by a step less half a width. Every
    // plan below starts from it (rings, fronts, rungs).
    let front1 = offset(below_loc, step - w / 2.0);
    if thin {
        // Where the perimeter is within an eighth of a width of biting like loop 1, it is
        // moved there: a marginal slope (60 degrees at 0.2 mm) then rests on the layer below
        // instead of hanging a tenth of a millimetre past it.
        // Where the outline lies on the layer below's edge (a wall's side standing on a
        // shelf's edge, the wall's inside hollow: the ring over air runs inward from the
        // outline), the perimeter there rests where the slicer put it and loops lean on the
        // layer below beside it: the outline is taken past that edge, so that no moved
        // perimeter is laid there, between the layer below and the loops.
        // (Closed by an eighth of a width: where the outline runs along the edge below, the
        // two leave slits a micrometre wide, which the pull-in opened into notches.)
        let ext = without_specks(
            closing(
                &union(&area_loc, &intersection(below_loc, &offset(&area_loc, we))),
                w / 8.0,
            ),
            w,
        );
        let pulled = union(
            &perimeter_area,
            &offset(&offset(&ext, -(we / 2.0 + inset + round)), round),
        );
        let biting = intersection(&pulled, &front1);
        let limit = offset(&ext, -(we / 2.0 + inset + w / 8.0));
        // Where the two lie a sliver apart (the wall below on the ring's inner side, a hollow
        // part's void beyond it) they are one: the sliver's two edges were two strands
        // 0.015 mm apart along each side of a hollow inverted pyramid, on every layer.
        perimeter_area = closing(&union(&biting, &limit), w / 8.0);
    } else if inset > 0.0 {
        // The inset puts the perimeter on the loops; where the zone has no room for them (a
        // region's thin arm along a flared wall) it only takes the perimeter off what the
        // layer above was sliced on (a hull's sides: the layer above 23.6 -> 52.2 mm in
        // air): there the perimeter stays where the slicer put it.
        let plain = offset(&offset(&area_loc, -(we / 2.0 + round)), round);
        let by_loops = offset(&inner, contour_at + w);
        perimeter_area = union(&perimeter_area, &difference(&plain, &by_loops));
        // Nor where the layer above prints past the outline: pulled in there, the perimeter
        // only widened the gap the layer above bridges (an arch's crown by Cura: 70.8 ->
        // 74.9 mm bridged on the layer above, 0.1 mm more on each of its strands).
        if !others.overhung.0.is_empty() {
            // The layer above's region lies the tolerance or more past the outline, the
            // perimeter's centre half a width (and the inset) inside it.
            let beyond = offset(&others.overhung, widths.tolerance + 1.5 * we + inset);
            // Its corners sharp there too, as the slicer drew them: a star's tip rounded by
            // half a width lost 0.5 mm, which the layer above's tip then bridged.
            let sharp = offset(&area_loc, -(we / 2.0));
            perimeter_area = union(&perimeter_area, &intersection(&sharp, &beyond));
        }
    }
    let perimeter = clip_lines(&rings(&perimeter_area), &zone, true);
    'thin: {
        if !thin {
            break 'thin;
        }
        // Loops from the wall below outward, `step` apart like any region's, where the
        // perimeter would not rest on what lies inside it: loop k goes where its centre is
        // at least [`NEAR_LOOP_AT`] widths inside the perimeter's, of full width where it is
        // [`HALF_LOOP_AT`] inside or more, of half width nearer (a full loop there would lie
        // almost under the perimeter). The perimeter is then less than 0.8 w from the last
        // loop's centre, within a quarter width of its edge, where a strip wider than a bead (an
        // arch's last layers, a sphere near its equator) once left it hanging.
        let near_at = NEAR_LOOP_AT;
        let near_room = intersection(&zone, &offset(&perimeter_area, -near_at * w));
        let full_room = offset(&perimeter_area, -HALF_LOOP_AT * w);
        // Where a half-width loop goes, measured where the full one would lie.
        let near_half = intersection(&zone, &offset(&perimeter_area, -(near_at + HALF_BACK) * w));
        // Under the perimeter's inner side at all: where a ring most of which is needed is
        // laid whole (see below).
        let under = intersection(&zone, &offset(&perimeter_area, -UNDER_AT * w));
        let extent =
            geo::BoundingRect::bounding_rect(&zone).map_or(0.0, |b| b.width().hypot(b.height()));
        let mut at = start;
        let mut strands = Vec::new();
        let mut loops = 0;
        let mut held = 0;
        let mut growth = crate::geometry::Growth::new(below_loc);
        // Where the next full-width ring's centre lies past the wall below. A ring goes a
        // step past a full one (a tenth of a width past its edge), but nearer a half-width
        // one, whose edge is a quarter width nearer: a step less a quarter width past it
        // (at a full step, a bow's tip got two half-width rings 0.27 mm apart, the second's
        // centre 0.16 mm past the first's edge: in air).
        let mut next_at = step - w / 2.0;
        // After a half-width ring the next goes at least half a step on (at an overlap of
        // 0.75 or more a step is a quarter width or less, and a full one holds anyway).
        let after_half = (step - w / 4.0 - HALF_BACK * w).max(step / 2.0);
        let rings_most = (extent.min(2000.0) / after_half).ceil() as usize + 2;
        for k in 1..=rings_most {
            let ring = if k == 1 {
                rings(&front1)
            } else {
                rings(&growth.at(next_at))
            };
            let mut pieces = clip_lines(&ring, &near_room, true);
            if pieces.is_empty() {
                break;
            }
            let length = |v: &[Polyline]| v.iter().map(|p| polyline_length(p)).sum::<f64>();
            // A ring most of which is needed is laid wherever it lies under the perimeter: a
            // faceted wall (a dome closing round its hole) puts a ring near the mark in and
            // out of it every facet, and the short pieces were dropped, leaving the perimeter
            // 0.35 mm past the loop before (22 mm in air on one layer).
            let whole = clip_lines(&ring, &under, true);
            let needed = length(&pieces) >= RING_NEEDED * length(&whole);
            if needed {
                pieces = whole;
            }
            // Pieces a ring's gaps of less than a width apart are one: the top infill of a
            // shelf a hollow wall stands on turns in notches along its edge every 1.1 mm,
            // the first ring bends round each and was cut there into pieces too short to
            // lay, and the loops began a step out, in air (25.6 mm on the layer).
            pieces = chained(&pieces, w);
            let shape = |width: f64| Shape {
                kind: StrandKind::Loop,
                loop_index: k,
                width,
            };
            let before = strands.len();
            if held > PLAN_POINTS {
                return no_plan(MultiPolygon::new(Vec::new()));
            }
            // Full width where most of the ring lies well inside the perimeter, half width
            // (a little nearer the loop before it, [`HALF_BACK`]) where most lies close
            // under it: decided for the whole ring, since a faceted wall puts a ring near
            // the mark in and out of it every few millimetres, and pieces that short were
            // dropped, leaving no loop at all.
            let inside_full = length(&clip_lines(&pieces, &full_room, true));
            let advance = if inside_full >= 0.5 * length(&pieces) {
                strands.extend(shape(w).strands(pieces, 2.0 * w, &mut at));
                step
            } else {
                let half_ring = rings(&growth.at(next_at - HALF_BACK * w));
                let half = if needed {
                    clip_lines(&half_ring, &under, true)
                } else {
                    clip_lines(&half_ring, &near_half, true)
                };
                let (full, half) = full_stretches(&pieces, half, &full_room, w);
                strands.extend(shape(w).strands(full, 2.0 * w, &mut at));
                let halves = strands.len();
                strands.extend(shape(w / 2.0).strands(half, 2.0 * w, &mut at));
                if strands.len() > halves {
                    after_half
                } else {
                    step
                }
            };
            next_at += advance;
            held += strands[before..]
                .iter()
                .map(|s| s.points.len())
                .sum::<usize>();
            if strands.len() > before {
                // Rings are offsets of the wall below: one laid [`DETACHED`] rings or more
                // past the last one laid (or the wall) rests on nothing. A long one means
                // the region is no gradual overhang's ring, however narrow: a wheel's rim on
                // spokes too narrow for a ring piece (0.6 mm nozzle) had its rings laid
                // round it in air, 104 mm each. The fronts below cross such strips as
                // rungs. (A bit of one, a window's far corner, stays: the region's plan
                // without it left more in air.)
                let laid: f64 = strands[before..].iter().map(|s| s.length()).sum();
                if k >= loops + DETACHED && laid > CANTILEVER_REACH {
                    break 'thin;
                }
                loops = k;
            }
        }
        if loops == 0 && region.max_distance > CANTILEVER_REACH {
            if let Some(plan) = ladder(&zone, &front1, w, step, start) {
                return plan;
            }
        }
        strands.extend(Shape::perimeter(we).strands(perimeter, we, &mut at));
        // The slicer's perimeter along the ring is taken out: what replaces it must run
        // along it too. A ring one bead wide stepping inward has no room for a moved
        // perimeter once pulled in from both sides, nor for a loop (a hollow torus's top
        // closing, one perimeter: 176 mm of the slicer's taken out, 1 mm written): left as
        // sliced.
        let along: f64 = rings(&zone).iter().map(|r| polyline_length(r)).sum::<f64>() / 2.0;
        let laid: f64 = strands.iter().map(|s| s.length()).sum();
        if laid < MOVED_SHARE * along {
            return no_plan(zone);
        }
        // The slicer's strands are taken out only where these run along them: a ring whose
        // moved perimeter is clipped away along part of it (a strip there narrower than the
        // perimeter's pull-in: a box chamfered on two sides, the sides' 0.3 mm) kept nothing
        // there, and the slicer's wall on those sides was lost, layer after layer.
        let reach = we / 2.0 + inset + w / 4.0;
        let along_new = crate::geometry::area::Strands::of_lines(
            strands
                .iter()
                .map(|s| (&s.points[..], s.width + 2.0 * reach)),
        )
        .buffer();
        let zone = intersection(&zone, &along_new);
        arrange(&mut strands, start);
        split_perimeters(&mut strands, start);
        return Plan {
            zone,
            strands,
            loops,
            with_perimeter: true,
            ladder: false,
        };
    }

    // The contour runs inside the perimeter all along the outline; only the side of the
    // loop area that follows the wall below is left out. (Leaving out all within half a
    // width of the wall below cut the contour to pieces on a strip about as wide as that,
    // a sphere's ring next to the equator, and the perimeter hung between them.)
    let near_below = offset(below_loc, w / 8.0);
    let contour = clip_lines(&rings(&inner), &near_below, false);
    // Contour pieces within a quarter width of the wall below rest on it as loop 1 does,
    // and loops lean on them: they are laid first, not last (a one-perimeter box's roof by
    // PrusaSlicer, its bridge's anchor strip over the gap inside the wall: the contour along
    // the outer bead came last and the loop beside it hung, 31 mm on one side).
    let (held_contour, contour) = if contour.is_empty() {
        (Vec::new(), contour)
    } else {
        let by_wall = offset(below_loc, w / 4.0);
        // (Pieces shorter than [`HELD_CONTOUR`] widths stay with the contour: beside a wall
        // the contour only touches here and there, moving them made hops between them, a
        // shelf's strip over a hollow block 11 -> 16 strands, its travel 37 -> 43 mm.)
        let held: Vec<Polyline> = clip_lines(&contour, &by_wall, true)
            .into_iter()
            .filter(|p| polyline_length(p) >= HELD_CONTOUR * w)
            .collect();
        if held.is_empty() {
            (held, contour)
        } else {
            // The rest of the contour, cut only where the held pieces were taken out.
            let taken =
                crate::geometry::area::Strands::of_lines(held.iter().map(|p| (&p[..], 0.02)))
                    .buffer();
            let rest = clip_lines(&contour, &taken, false);
            (held, rest)
        }
    };

    // Fronts grow inside the zone only (a geodesic offset): past a hole in the region they
    // wrap around it instead of jumping across, so every loop lies beside the previous one.
    // Each front is the previous one grown by one step and cut back to where loops may go.
    // Only the front within a step of `inner` can grow into it: the rest of sectA's outline
    // is left out, which keeps every step's offset and cut small.
    let near = offset(&inner, 2.0 * step + w);
    let first = intersection(&front1, &near);
    let mut allowed = union(&inner, &first);
    // The strips (see below) added to where fronts grow; with no loop printed yet, the fronts
    // also start where the strips leave the wall below.
    let widen = |from: &MultiPolygon<f64>,
                 allowed: &mut MultiPolygon<f64>,
                 loops: &[Vec<Polyline>]|
     -> MultiPolygon<f64> {
        let strip = intersection(&zone, &offset(&area_loc, -(we / 2.0 + inset)));
        *allowed = union(allowed, &strip);
        if loops.iter().all(|l| l.is_empty()) {
            let near = offset(&strip, 2.0 * step + w);
            union(from, &intersection(&front1, &near))
        } else {
            from.clone()
        }
    };
    // Ring parts on the cut are not fronts: clip to just inside the loop area.
    let strictly_inner = offset(&inner, -0.01);
    // The loop area a front has not come within a step of (none where it fills what it may
    // grow in, as it does when the loops end: no boolean then).
    let unreached = |f: &MultiPolygon<f64>, allowed: &MultiPolygon<f64>| {
        if allowed.unsigned_area() - f.unsigned_area() < w * w {
            0.0
        } else {
            difference(&inner, &offset(f, step)).unsigned_area()
        }
    };
    // Strips of the zone narrower than a contour and a perimeter each side hold no loop
    // area, or a thread of it (a wheel's spokes, the sides of a beam past a hole near its
    // tip): a front crossing one has nothing to print, and what lies past it was left empty
    // or its strands hanging. Where fronts cross a strip for [`CROSSING`] steps, or stop
    // short of a part of the loop area, they are grown again from where the crossing began
    // through the strips, printed there as rungs across them (each biting into the one
    // before, as a narrow cantilever's ladder) and in the loop area as before.
    let mut rungs: Option<MultiPolygon<f64>> = None;
    let mut widened = false;
    // Rungs stay half a width clear of the loop area (the contour runs on its edge: the
    // last rung bites into it as loops do into each other; a width clear, the front between
    // printed nothing, and where a bar meets a ring hanging from it the ring's first loops
    // hung past the last rung, 1.7 mm in air), its threads narrower than half a width left
    // out (the loop area's thread down a spoke took the whole spoke).
    let rungs_in = |allowed: &MultiPolygon<f64>| {
        difference(
            &offset(allowed, -0.01),
            &offset(&opening(&inner, w / 4.0), w / 2.0),
        )
    };
    // The front and the loop count where the fronts last began to print nothing.
    let mut empty_since: Option<(MultiPolygon<f64>, usize)> = None;
    let mut loops: Vec<Vec<Polyline>> = Vec::new();
    // (loop index, piece) of the pieces too short to lay by themselves.
    let mut shorts: Vec<(usize, Polyline)> = Vec::new();
    let mut held = 0;
    let mut front = first;
    // The region's reach is measured to the nearest material below, which may be another
    // object's across a gap that no front crosses (the fronts grow from what the zone
    // touches): the loops may have to go as far as the zone extends. The growth stops by
    // itself where the zone is filled; this only bounds it.
    let extent =
        geo::BoundingRect::bounding_rect(&zone).map_or(0.0, |b| b.width().hypot(b.height()));
    let max_loops = (reach.max(extent.min(2000.0)) / step).ceil() as usize + 2;
    let mut steps = 0;
    while steps < 2 * max_loops {
        steps += 1;
        let ring = rings(&front);
        // Pieces shorter than half a width are not laid, unless a piece of the next loop
        // rests on nothing else (see below): those of a quarter width or more are kept aside.
        let shorts_before = shorts.len();
        let mut inside = |area: &MultiPolygon<f64>| -> Vec<Polyline> {
            let (long, short): (Vec<Polyline>, Vec<Polyline>) = clip_lines(&ring, area, true)
                .into_iter()
                .filter(|p| polyline_length(p) >= w / 4.0)
                .partition(|p| polyline_length(p) >= w / 2.0);
            shorts.extend(short.into_iter().map(|p| (loops.len(), p)));
            long
        };
        let mut pieces = inside(&strictly_inner);
        if let Some(r) = &rungs {
            pieces.extend(inside(r));
        }
        if !pieces.is_empty() {
            empty_since = None;
        } else if empty_since.is_none() {
            empty_since = Some((front.clone(), loops.len()));
        }
        // Fronts end where the zone is filled: after a loop, the first front with nothing
        // left to print. The first fronts of an arm anchored only at its end may be slivers
        // too small to print: the growth goes on through them (it stopped after two, and
        // one of a cylinder's two identical wings got no loop at all); so it does where the
        // loop area has a part no front came near (past a strip).
        let crossing = empty_since.as_ref().is_some_and(|(_, n)| {
            loops.len() - n >= CROSSING && loops[..*n].iter().all(|l| l.is_empty())
        });
        if pieces.is_empty() {
            let left = unreached(&front, &allowed) >= w * w;
            if !left && loops.iter().any(|l| !l.is_empty()) {
                break;
            }
            if left && crossing && !widened {
                let (from, n) = empty_since.take().expect("crossing");
                loops.truncate(n);
                shorts.retain(|(i, _)| *i < n);
                front = widen(&from, &mut allowed, &loops);
                widened = true;
                rungs = Some(rungs_in(&allowed));
                continue;
            }
        }
        held += points_of(&pieces)
            + shorts[shorts_before..]
                .iter()
                .map(|(_, p)| p.len())
                .sum::<usize>();
        if held > PLAN_POINTS {
            return no_plan(MultiPolygon::new(Vec::new()));
        }
        loops.push(pieces);
        let next = grow_within(&front, step, &allowed);
        if (next.unsigned_area() - front.unsigned_area()).abs() < 1e-6 {
            if widened || unreached(&front, &allowed) < w * w {
                break;
            }
            // Stopped short: the loop area comes apart at a strip. Past loops, the fronts go
            // on through it from where they stopped, printing in the loop area only (rungs
            // from there left more in air: a beam's tip past a hole 1.6 -> 2.8 mm).
            widened = true;
            if loops.iter().any(|l| !l.is_empty()) {
                front = widen(&front, &mut allowed, &loops);
            } else {
                let (from, n) = empty_since.take().unwrap_or((front.clone(), loops.len()));
                loops.truncate(n);
                shorts.retain(|(i, _)| *i < n);
                front = widen(&from, &mut allowed, &loops);
                rungs = Some(rungs_in(&allowed));
                continue;
            }
            let next = grow_within(&front, step, &allowed);
            if (next.unsigned_area() - front.unsigned_area()).abs() < 1e-6 {
                break;
            }
            front = next;
            continue;
        }
        front = next;
    }
    while loops.last().is_some_and(|l| l.is_empty()) {
        loops.pop();
    }
    shorts.retain(|(i, _)| *i < loops.len());
    keep_needed_shorts(&mut loops, shorts, step);

    let mut at = start;
    // A thin strip of the zone that no loop reaches (a chamfer's ring running into a hole's
    // ceiling closing beside it, one region): the perimeter there stays as sliced, and where
    // it would hang [`NEAR_LOOP_AT`] widths or more past the wall below, a half-width loop is
    // laid under it first, as on a gradual overhang's ring (a block's 45-degree chamfer by
    // PrusaSlicer at 0.3 mm: 47 mm of its perimeter in air on one layer).
    let strip = difference(
        &intersection(&zone, &offset(&perimeter_area, -NEAR_LOOP_AT * w)),
        &offset(&inner, w),
    );
    let mut strands: Vec<Strand> = if strip.0.is_empty() {
        Vec::new()
    } else {
        let ring = rings(&offset(below_loc, step - w / 2.0 - HALF_BACK * w));
        let shape = |width: f64| Shape {
            kind: StrandKind::Loop,
            loop_index: 1,
            width,
        };
        // Where the perimeter hangs farther (a flatter face), the full loop (see
        // [`full_stretches`]).
        let full_ring = clip_lines(&rings(&front1), &strip, true);
        let full_room = offset(&perimeter_area, -HALF_LOOP_AT * w);
        let (full, half) =
            full_stretches(&full_ring, clip_lines(&ring, &strip, true), &full_room, w);
        let mut v = shape(w).strands(full, 2.0 * w, &mut at);
        v.extend(shape(w / 2.0).strands(half, 2.0 * w, &mut at));
        v
    };
    let held_by_wall = Shape {
        kind: StrandKind::Loop,
        loop_index: 1,
        width: w,
    };
    strands.extend(held_by_wall.strands(held_contour, w, &mut at));
    let ordered = order_loops(loops, step, w, seam_stagger(w, step), &mut at.clone());
    // The loops with the next loops' bits laid from the rings that hold them, kept where
    // the whole plan so travels less (bits close together along a ring were reached one
    // from the next, and each spliced one returns to the ring).
    let assembled = |seq: Vec<(usize, Polyline)>, contour: Vec<Polyline>, perimeter| {
        assemble(
            &strands,
            seq,
            contour,
            perimeter,
            (w, we, below_loc),
            at,
            start,
        )
    };
    let strands = match splice_into_rings(&ordered, step, w) {
        Some(spliced) => {
            let a = assembled(spliced, contour.clone(), perimeter.clone());
            let b = assembled(ordered, contour, perimeter);
            if hop_travel(&a) < hop_travel(&b) {
                a
            } else {
                b
            }
        }
        None => assembled(ordered, contour, perimeter),
    };
    let loops_count = strands
        .iter()
        .filter(|s| s.kind == StrandKind::Loop)
        .map(|s| s.loop_index)
        .max()
        .unwrap_or(0);
    // A narrow cantilever whose loop area is a thread along it (a lying cylinder's first
    // layer at 0.12 mm, 1.3 mm wide and 16 mm out from its post: room for a contour round a
    // 0.23 mm thread, none for a loop across it) got its contour and perimeter laid along
    // it in air. Where the loops leave part of the zone beyond the contour and perimeter
    // that would lean on them (a rim on spokes too narrow for a loop: a third of it), and
    // a ladder's rungs cover more, the ladder is taken.
    if region.max_distance > CANTILEVER_REACH {
        // Share of the zone within `reach` of the loops' beads (sampled: the beads' union
        // of a big cap's 140 loops cost 70 ms).
        let covered = |strands: &[Strand], reach: f64| {
            let lines: Vec<(&[[f64; 2]], f64)> = strands
                .iter()
                .filter(|s| s.kind == StrandKind::Loop)
                .map(|s| (&s.points[..], s.width / 2.0 + reach))
                .collect();
            crate::geometry::coverage::share_within(&zone, &lines, w / 2.0)
        };
        let by_loops = covered(&strands, contour_at + we / 2.0);
        if by_loops < COVERED_SHARE {
            if let Some(plan) = ladder(&zone, &front1, w, step, start) {
                if covered(&plan.strands, 0.0) > by_loops {
                    return plan;
                }
            }
        }
    }
    Plan {
        zone,
        strands,
        loops: loops_count,
        with_perimeter: false,
        ladder: false,
    }
}

/// Least share of a narrow cantilever's zone its loops, with the contour and perimeter along
/// them, cover before its [`ladder`] is tried instead ([`plan_in`]): a plan that holds
/// covers all of it, one whose loops stop short (a rim on narrow spokes) 64 % or less.
const COVERED_SHARE: f64 = 0.9;

/// Rings of a thin region's plan with nothing laid between the last one laid (or the wall
/// below) and one that is: that one rests on nothing ([`plan_in`]).
const DETACHED: usize = 4;

/// Shortest piece of the contour (in widths) resting on the wall below that is laid before
/// the loops ([`plan_in`]).
const HELD_CONTOUR: f64 = 8.0;

/// Least share of a thin ring's length that its loops and moved perimeter together run
/// along ([`plan_in`]): a hollow torus's closing ring kept 0.6 % of it, short rings round a
/// post's flare (4 mm) keep 27 %.
const MOVED_SHARE: f64 = 0.15;

/// Steps a front may print nothing while part of the loop area lies ahead before it is
/// taken for one crossing a strip ([`plan_in`]): the first fronts of an arm held at its end
/// are slivers for a step or two.
const CROSSING: usize = 3;

/// A thin region with no loop reaching farther than this (mm) from what holds it is a narrow
/// cantilever, not a gradual overhang's ring: [`ladder`]. Shorter ones (a letter's stroke
/// 3 mm out of a wall) keep the slicer's loop out and back, its perimeter moved onto the
/// layer below: a short bridge held at both ends (rungs there left more in air over
/// lettering: 13.5 -> 27.3 mm).
const CANTILEVER_REACH: f64 = 5.0;

/// The plan of a narrow cantilever: a strip no wider than a bead or two that holds on at one
/// end only (the tangent layer of a horizontal cylinder's underside, a coat hook's arm at
/// 0.15 mm layers: 26 mm long, 0.7 mm wide, its one perimeter loop all in air). No ring of the
/// layer below runs beside it, and the strip has no room for a contour: the zone is printed
/// as short strands across it, each a step farther from the wall below than the one before,
/// from the wall outward (a ladder), each biting into the last; no perimeter, since the rungs
/// fill the strip. `None` when no rung fits.
fn ladder(
    zone: &MultiPolygon<f64>,
    front: &MultiPolygon<f64>,
    w: f64,
    step: f64,
    start: [f64; 2],
) -> Option<Plan> {
    // The rungs are the fronts of a growth inside the zone from loop 1's ring (`front`: the
    // layer below grown by a step less half a width), a step at a time, as a wide region's
    // loops grow: each step offsets the strip's small front, not the whole layer below by
    // the rung's distance (that doubled the time of a plate of four hooks).
    let near = offset(zone, 2.0 * step + w);
    let first = intersection(front, &near);
    let allowed = union(zone, &first);
    let inside = offset(zone, -0.01);
    let extent =
        geo::BoundingRect::bounding_rect(zone).map_or(0.0, |b| b.width().hypot(b.height()));
    // Rungs of front k at index k - 1.
    let mut fronts: Vec<Vec<Polyline>> = Vec::new();
    let mut loops = 0;
    let mut held = 0;
    let mut front = first;
    for k in 1..=(extent.min(2000.0) / step).ceil() as usize + 2 {
        let pieces: Vec<Polyline> = clip_lines(&rings(&front), &inside, true)
            .into_iter()
            .filter(|p| polyline_length(p) >= w / 4.0)
            .collect();
        if pieces.is_empty() && loops > 0 {
            break;
        }
        held += points_of(&pieces);
        if held > PLAN_POINTS {
            return None;
        }
        if !pieces.is_empty() {
            loops = k;
        }
        fronts.push(pieces);
        let next = grow_within(&front, step, &allowed);
        if (next.unsigned_area() - front.unsigned_area()).abs() < 1e-6 {
            break;
        }
        front = next;
    }
    // Each rung after the rungs it rests on, an arm's rungs one after the other before the
    // next arm's (laid front by front, a wheel's rim reached along five spokes hopped from
    // spoke to spoke at every front: 2 961 mm of travel for 767 mm of rungs).
    let mut at = start;
    let mut strands: Vec<Strand> = order_loops(fronts, step, w, 0.0, &mut at)
        .into_iter()
        .map(|(i, points)| Strand {
            kind: StrandKind::Loop,
            loop_index: i + 1,
            points,
            width: w,
        })
        .collect();
    arrange(&mut strands, start);
    (loops > 0).then(|| Plan {
        zone: zone.clone(),
        strands,
        loops,
        with_perimeter: false,
        ladder: true,
    })
}

/// How far (in steps) a piece's box may lie from the box of a piece of the loop before for
/// that one to count as its support ([`order_loops`], [`keep_needed_shorts`]).
const SUPPORT_REACH: f64 = 1.5;

/// Puts back into `loops` the short pieces (loop index, piece) that a piece of the next loop
/// needs: one with no piece of the loop before near it (within [`order_loops`]'s reach of a
/// support) takes that loop's short pieces near it, and so on down. Where a bar meets a ring
/// hanging from it, the fronts' first pieces across the bar are a little shorter than half a
/// width; dropped, the next loop's first rung there lay 0.6 mm past the wall below with
/// nothing under it (0.5 mm in air).
fn keep_needed_shorts(loops: &mut [Vec<Polyline>], shorts: Vec<(usize, Polyline)>, step: f64) {
    type Boxed = (Option<geo::Rect<f64>>, Polyline);
    let grow = SUPPORT_REACH * step;
    let near = |a: &Option<geo::Rect<f64>>, b: &Option<geo::Rect<f64>>| {
        crate::geometry::boxes_within(a.as_ref(), b.as_ref(), grow)
    };
    // Boxes once per piece (a ring's thousands of points), shorts by their loop.
    let mut boxes: Vec<Vec<Option<geo::Rect<f64>>>> = loops
        .iter()
        .map(|l| l.iter().map(|p| crate::geometry::points_box(p)).collect())
        .collect();
    let mut by_loop: Vec<Vec<Boxed>> = vec![Vec::new(); loops.len()];
    for (i, p) in shorts {
        if let Some(v) = by_loop.get_mut(i) {
            v.push((crate::geometry::points_box(&p), p));
        }
    }
    for i in (1..loops.len()).rev() {
        if by_loop[i - 1].is_empty() {
            continue;
        }
        let alone: Vec<&Option<geo::Rect<f64>>> = boxes[i]
            .iter()
            .filter(|b| !boxes[i - 1].iter().any(|q| near(b, q)))
            .collect();
        if alone.is_empty() {
            continue;
        }
        let needed: Vec<Boxed> = std::mem::take(&mut by_loop[i - 1])
            .into_iter()
            .filter(|(b, _)| alone.iter().any(|a| near(a, b)))
            .collect();
        for (b, p) in needed {
            boxes[i - 1].push(b);
            loops[i - 1].push(p);
        }
    }
}

/// Orders the loops' pieces (loop `i` at index `i`) so that each piece rests on what is
/// already printed and the nozzle moves little: the next piece is the nearest one whose
/// supports are all printed, a support being any piece of the loop before whose box, grown
/// by one and a half steps, meets its box. A region split in lobes (by a hole, or a narrow
/// waist) so gets each lobe's loops one after the other, instead of crossing over at every
/// loop. Returns (loop index, piece) in print order; updates `at` to the last end.
///
/// A closed loop starts `stagger` mm along from the point nearest the previous loop's end, so
/// that the seams of successive rings do not stack into one line across the region (each
/// ring's seam would sit beside the one before: a weak, lumpy radial line); see
/// [`seam_stagger`].
fn order_loops(
    loops: Vec<Vec<Polyline>>,
    step: f64,
    width: f64,
    stagger: f64,
    at: &mut [f64; 2],
) -> Vec<(usize, Polyline)> {
    let mut pieces: Vec<(usize, Polyline, Option<geo::Rect<f64>>)> = Vec::new();
    for (i, ps) in loops.into_iter().enumerate() {
        for p in ps {
            let b = crate::geometry::points_box(&p);
            pieces.push((i, p, b));
        }
    }
    let n = pieces.len();
    let grow = SUPPORT_REACH * step;
    let meets = |a: &Option<geo::Rect<f64>>, b: &Option<geo::Rect<f64>>| {
        crate::geometry::boxes_within(a.as_ref(), b.as_ref(), grow)
    };
    // Supports of each piece: indices of pieces of the loop before that it may rest on. A
    // piece with none there (the first loop past a strip the fronts crossed as rungs, kept
    // a width clear of the loop area; a front past steps too short to print) rests on what
    // lower loops laid near it: without, it was free from the start, and the nearest free
    // piece is printed next, however far out.
    let supports: Vec<Vec<usize>> = (0..n)
        .map(|k| {
            let i = pieces[k].0;
            let next: Vec<usize> = (0..n)
                .filter(|&j| pieces[j].0 + 1 == i && meets(&pieces[j].2, &pieces[k].2))
                .collect();
            if !next.is_empty() || i == 0 {
                return next;
            }
            (0..n)
                .filter(|&j| {
                    let (lower, box_j) = (pieces[j].0, &pieces[j].2);
                    lower < i && {
                        let reach = 2.0 * width + (i - lower) as f64 * step;
                        crate::geometry::boxes_within(box_j.as_ref(), pieces[k].2.as_ref(), reach)
                    }
                })
                .collect()
        })
        .collect();
    let mut done = vec![false; n];
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        let mut best: Option<(f64, usize)> = None;
        for k in (0..n).filter(|&k| !done[k]) {
            if !supports[k].iter().all(|&j| done[j]) {
                continue;
            }
            let d = start_distance2(&pieces[k].1, *at);
            // Lower loops first on a tie, as the plain order would.
            if best.is_none_or(|(bd, bk)| d < bd || (d == bd && pieces[k].0 < pieces[bk].0)) {
                best = Some((d, k));
            }
        }
        // Supports always form a chain down to loop 1, so some piece is always free.
        let Some((_, k)) = best else { break };
        done[k] = true;
        let mut p = std::mem::take(&mut pieces[k].1);
        if is_closed(&p) {
            // From the nearest point (not vertex: a ring's straight sides have none), then
            // along by the stagger.
            start_at_nearest_point(&mut p, *at);
            stagger_seam(&mut p, stagger);
        } else {
            start_nearest(&mut p, *at);
        }
        *at = p[p.len() - 1];
        out.push((pieces[k].0, p));
    }
    out
}

/// Farthest (in widths) a fragment of the next loop may end from where its ring resumes
/// ([`splice_into_rings`]).
const SPLICE_RETURN: f64 = 8.0;

/// Lays the short open pieces of loop `i + 1` that rest on a closed ring of loop `i` alone
/// while that ring is printed, instead of after it: the ring is cut just past the stretch
/// that holds a piece, the piece laid from its end there back along the ring (and after it
/// the pieces of the loops beyond that rest on it alone, each from its end nearer the last
/// one's), then the ring resumed where it was cut. A square ledge's loops grow round its
/// corners as arcs, so once the sides reach the edge the next loops are four corner bits
/// each; laid after the ring, each corner was a retraction and a travel along a side (a
/// 14 mm ledge: 44 mm of travel for 376 mm of loops); spliced, a step out from the ring and
/// one back along the bits.
///
/// A piece joins only when every point of it lies within two steps and a width of the piece
/// it rests on, it rests on nothing else of that loop laid after the ring, the stretch of
/// ring under the first does not hold the ring's seam, and the last one's far end lies within
/// [`SPLICE_RETURN`] widths of the cut; so each piece still follows all it rests on.
fn splice_into_rings(
    seq: &[(usize, Polyline)],
    step: f64,
    w: f64,
) -> Option<Vec<(usize, Polyline)>> {
    let reach = 2.0 * step + w;
    let n = seq.len();
    let boxes: Vec<Option<geo::Rect<f64>>> = seq
        .iter()
        .map(|(_, p)| crate::geometry::points_box(p))
        .collect();
    let near_box = |j: usize, k: usize| {
        crate::geometry::boxes_within(boxes[j].as_ref(), boxes[k].as_ref(), reach)
    };
    // Whether every point of `piece` lies within `reach` of the polyline `under`.
    let rests_on = |piece: &Polyline, under: &Polyline| {
        piece.iter().all(|q| {
            under.windows(2).any(|seg| {
                let (_, m) = crate::geometry::nearest_on_segment(*q, seg[0], seg[1]);
                dist2(*q, m) <= reach * reach
            })
        })
    };
    let mut taken = vec![false; n];
    // Per ring (by position): (cut mm along it, the pieces laid there in order).
    let mut chains: Vec<Vec<(f64, Vec<usize>)>> = vec![Vec::new(); n];
    // The running lengths of the rings cut, for the second pass.
    let mut lengths: Vec<Vec<f64>> = vec![Vec::new(); n];
    for (r, (li, ring)) in seq.iter().enumerate() {
        if !is_closed(ring) {
            continue;
        }
        let cum = running_lengths(ring);
        let total = cum[cum.len() - 1];
        // Where along the ring the point nearest `q` lies, and how far off.
        let along = |q: [f64; 2]| -> (f64, f64) {
            let mut best = (f64::INFINITY, 0.0);
            for (i, seg) in ring.windows(2).enumerate() {
                let (t, m) = crate::geometry::nearest_on_segment(q, seg[0], seg[1]);
                let d = dist2(q, m);
                if d < best.0 {
                    best = (d, cum[i] + t * (cum[i + 1] - cum[i]));
                }
            }
            (best.0.sqrt(), best.1)
        };
        // The next free open piece of loop `next` resting on piece `on` alone (of the
        // pieces of its loop laid after the ring).
        let fits = |on: usize, next: usize, k: usize, taken: &[bool]| {
            let piece = &seq[k].1;
            seq[k].0 == next
                && !taken[k]
                && piece.len() >= 2
                && !is_closed(piece)
                && near_box(on, k)
                && !(r + 1..n).any(|j| j != on && seq[j].0 + 1 == next && near_box(j, k))
                && rests_on(piece, &seq[on].1)
        };
        let follower =
            |on: usize, next: usize, taken: &[bool]| (r + 1..n).find(|&k| fits(on, next, k, taken));
        for k in r + 1..n {
            if !fits(r, li + 1, k, &taken) {
                continue;
            }
            let piece = &seq[k].1;
            let mut span = (f64::INFINITY, f64::NEG_INFINITY);
            for q in piece {
                let t = along(*q).1;
                span = (span.0.min(t), span.1.max(t));
            }
            // The stretch under it must not hold the seam (it would run round the end).
            if span.1 - span.0 > total / 2.0 || span.1 >= total - w {
                continue;
            }
            let cut = span.1;
            let at_cut = point_along(ring, &cum, cut);
            // The chain: the piece from its end nearer the cut, then what rests on it alone.
            let mut chain = vec![k];
            let mut end = far_end(piece, at_cut);
            let mut last = k;
            let mut lk = li + 1;
            let mut held = taken.clone();
            held[k] = true;
            while let Some(g) = follower(last, lk + 1, &held) {
                end = far_end(&seq[g].1, end);
                held[g] = true;
                chain.push(g);
                last = g;
                lk += 1;
            }
            if dist2(end, at_cut).sqrt() > SPLICE_RETURN * w {
                continue;
            }
            for &g in &chain {
                taken[g] = true;
            }
            chains[r].push((cut, chain));
        }
        if !chains[r].is_empty() {
            lengths[r] = cum;
        }
    }
    if !taken.iter().any(|&t| t) {
        return None;
    }
    let mut pieces: Vec<Option<(usize, Polyline)>> = seq.iter().cloned().map(Some).collect();
    let mut out = Vec::with_capacity(n + 8);
    for (r, mut cuts) in chains.into_iter().enumerate() {
        let Some((li, ring)) = pieces[r].take() else {
            continue;
        };
        if cuts.is_empty() {
            out.push((li, ring));
            continue;
        }
        cuts.sort_by(|x, y| x.0.total_cmp(&y.0));
        let cum = std::mem::take(&mut lengths[r]);
        let total = cum[cum.len() - 1];
        let mut from = 0.0;
        for (cut, chain) in cuts {
            if cut > from + 1e-6 {
                out.push((li, sub_polyline(&ring, &cum, from, cut)));
                from = cut;
            }
            let mut at = point_along(&ring, &cum, cut);
            for k in chain {
                let Some((lk, mut piece)) = pieces[k].take() else {
                    continue;
                };
                if dist2(piece[piece.len() - 1], at) < dist2(piece[0], at) {
                    piece.reverse();
                }
                at = piece[piece.len() - 1];
                out.push((lk, piece));
            }
        }
        out.push((li, sub_polyline(&ring, &cum, from, total)));
    }
    Some(out)
}

/// The strands of a plan: `prefix` (laid before the loops, ending at `at`), the loops in the
/// order `seq` gives, then the contour and perimeter, arranged from `start`.
fn assemble(
    prefix: &[Strand],
    seq: Vec<(usize, Polyline)>,
    contour: Vec<Polyline>,
    perimeter: Vec<Polyline>,
    (w, we, below): (f64, f64, &MultiPolygon<f64>),
    mut at: [f64; 2],
    start: [f64; 2],
) -> Vec<Strand> {
    let mut strands = prefix.to_vec();
    if let Some((_, p)) = seq.last() {
        at = p[p.len() - 1];
    }
    strands.extend(seq.into_iter().map(|(i, p)| Strand {
        kind: StrandKind::Loop,
        loop_index: i + 1,
        points: p,
        width: w,
    }));
    let early = interleave(&strands, &contour, &perimeter, (w, we), prefix.len(), below);
    strands.extend(finish_order(contour, perimeter, w, we, &mut at));
    arrange(&mut strands, start);
    let mut laid = match early {
        Some(mut e) => {
            arrange(&mut e, start);
            // Rings' seams on held points are worth a little travel.
            if hop_travel(&e) < hop_travel(&strands) + SEAM_SLACK * w {
                e
            } else {
                strands
            }
        }
        None => strands,
    };
    split_perimeters(&mut laid, start);
    laid
}

/// Travel (in widths) a plan whose rings start on held points may add to the one whose rings
/// start nearest the nozzle ([`assemble`]).
const SEAM_SLACK: f64 = 2.0;

/// Farthest (in widths) the nozzle goes out of its way, from where it is between or along
/// strands of loops and back, to lay a piece of the contour or the moved perimeter there
/// ([`interleave`]).
const FINISH_DETOUR: f64 = 6.0;

/// How far (in widths of the strand cut) past the bead of a strand laid before a cut in a
/// loop strand may lie ([`interleave`]): within the deposition check's own reach for
/// support (a quarter of a width), less a margin.
const HELD_CUT: f64 = 0.15;

/// Most (loop or pool point, pool point) pairs [`pull_forward`] weighs (its distance tests
/// run over such pairs: pool against loops, and pool against pool for what leans on what);
/// past it the pool follows the loops, as planned. A plate pierced by 16 holes: 23 million,
/// 10 ms.
const INTERLEAVE_WORK: usize = 50_000_000;

/// Whether a bead `width` wide is held at `p`: a strand of `laid` within [`HELD_CUT`] widths
/// past its bead, or the wall `below` within that of `p`.
fn held(laid: &[Strand], below: &MultiPolygon<f64>, p: [f64; 2], width: f64) -> bool {
    use geo::{Distance, Euclidean};
    laid.iter().any(|s| {
        let r = s.width / 2.0 + HELD_CUT * width;
        s.points.windows(2).any(|q| {
            let c = crate::geometry::nearest_on_segment(p, q[0], q[1]).1;
            dist2(c, p) <= r * r
        })
    }) || Euclidean.distance(&geo::Point::new(p[0], p[1]), below) <= HELD_CUT * width
}

/// The last point along `strand` (mm from its start, running lengths `cum`) within `reach`
/// of `piece`, sampled every `step` mm; `None` when none is.
fn last_near(
    strand: &Polyline,
    cum: &[f64],
    piece: &Polyline,
    reach: f64,
    step: f64,
) -> Option<f64> {
    let total = *cum.last()?;
    let near = |q: [f64; 2]| {
        piece.windows(2).any(|s| {
            let c = crate::geometry::nearest_on_segment(q, s[0], s[1]).1;
            dist2(c, q) <= reach * reach
        })
    };
    let j = (0..strand.len().saturating_sub(1))
        .rev()
        .find(|&j| crate::geometry::polylines_within(&strand[j..j + 2], piece, reach))?;
    let (t0, t1) = (cum[j], cum[j + 1]);
    let n = ((t1 - t0) / step).ceil().max(1.0) as usize;
    (0..=n)
        .rev()
        .map(|m| t0 + (t1 - t0) * m as f64 / n as f64)
        .find(|&t| near(point_along(strand, cum, t)))
        .or(Some(t0))
        .filter(|&t| t <= total)
}

/// `pieces` with those that meet end to end (within `gap`) joined into one: laid apart, the
/// first of two would end over air where the second, laid after it, held its end (a
/// perimeter cut in two along a shelf's edge: 1.1 mm in air once its halves were laid at
/// different times).
fn chained(pieces: &[Polyline], gap: f64) -> Vec<Polyline> {
    let mut out: Vec<Polyline> = pieces.to_vec();
    let g2 = gap * gap;
    'join: loop {
        for i in 0..out.len() {
            if out[i].len() < 2 || is_closed(&out[i]) {
                continue;
            }
            for j in i + 1..out.len() {
                if out[j].len() < 2 || is_closed(&out[j]) {
                    continue;
                }
                let (a0, a1) = (out[i][0], out[i][out[i].len() - 1]);
                let (b0, b1) = (out[j][0], out[j][out[j].len() - 1]);
                let mut b = out.swap_remove(j);
                let a = &mut out[i];
                if dist2(a1, b0) <= g2 {
                } else if dist2(a1, b1) <= g2 {
                    b.reverse();
                } else if dist2(a0, b1) <= g2 {
                    a.reverse();
                    b.reverse();
                } else if dist2(a0, b0) <= g2 {
                    a.reverse();
                } else {
                    out.push(b);
                    let last = out.len() - 1;
                    out.swap(j, last);
                    continue;
                }
                a.extend(b);
                continue 'join;
            }
        }
        return out;
    }
}

/// `loops` (in print order) with the pieces of the contour and the moved perimeter laid
/// among them: each piece as soon as every strand it leans on is printed (the loops within
/// a width of either bead, and for a perimeter piece the contour beside it, as in
/// [`finish_order`]) and the nozzle passes within [`FINISH_DETOUR`] widths of it, there and
/// back: between two strands, or along the last strand it leans on, once that strand is
/// past it (the strand is cut there and resumed after). The rest follow the loops, nearest
/// first, as [`finish_order`] lays them; a ring starts on a point a bead laid before (or the
/// wall below) holds. Nothing printed after a piece comes within reach of it.
/// A shelf pierced by holes grew its loops past hole after hole, then toured every hole
/// again for its contour and perimeter (16 holes: 11.7 % of the loops' length in travel).
/// `None` when the plan is too big to weigh ([`INTERLEAVE_WORK`]).
fn interleave(
    loops: &[Strand],
    contour: &[Polyline],
    perimeter: &[Polyline],
    (w, we): (f64, f64),
    first: usize,
    below: &MultiPolygon<f64>,
) -> Option<Vec<Strand>> {
    let piece = |kind: StrandKind, width: f64| {
        move |p: Polyline| Strand {
            kind,
            loop_index: 0,
            points: p,
            width,
        }
    };
    let pool: Vec<Strand> = chained(contour, w / 2.0)
        .into_iter()
        .filter(|p| polyline_length(p) >= w)
        .map(piece(StrandKind::Contour, w))
        .chain(
            chained(perimeter, we / 2.0)
                .into_iter()
                .filter(|p| polyline_length(p) >= we)
                .map(piece(StrandKind::Perimeter, we)),
        )
        .collect();
    pull_forward(loops, &pool, (w + we, w), first, below)
}

/// Which strands lean on which: loops on lower loops, the contour on loops, the moved
/// perimeter on both.
fn rank(s: &Strand) -> usize {
    match s.kind {
        StrandKind::Loop => s.loop_index,
        StrandKind::Contour => usize::MAX - 1,
        StrandKind::Perimeter => usize::MAX,
    }
}

/// `loops` (in print order) with the strands of `pool` laid among them: each as soon as every
/// strand it leans on is printed (those of a lower [`rank`] within `reach` of it) and the
/// nozzle passes within [`FINISH_DETOUR`] widths (`w`) of it, there and back: between two
/// strands, or along the last strand it leans on once that strand is past it (cut there, where
/// a strand laid before holds its bead, and resumed after). The rest follow, nearest first.
/// Nothing printed after a strand of the pool comes within reach of it but what leans on it.
/// `None` when the plan is too big to weigh ([`INTERLEAVE_WORK`]).
fn pull_forward(
    loops: &[Strand],
    pool: &[Strand],
    (reach, w): (f64, f64),
    first: usize,
    below: &MultiPolygon<f64>,
) -> Option<Vec<Strand>> {
    let loop_points: usize = loops.iter().map(|s| s.points.len()).sum();
    let piece_points: usize = pool.iter().map(|p| p.points.len()).sum();
    if pool.is_empty()
        || loops.len() <= first
        || (loop_points + piece_points).saturating_mul(piece_points) > INTERLEAVE_WORK
        || loops.iter().any(|s| s.points.len() < 2)
    {
        return None;
    }
    let boxes: Vec<Option<geo::Rect<f64>>> = pool
        .iter()
        .map(|p| crate::geometry::points_box(&p.points))
        .collect();
    let loop_boxes: Vec<Option<geo::Rect<f64>>> = loops
        .iter()
        .map(|s| crate::geometry::points_box(&s.points))
        .collect();
    let near_loop = |i: usize, k: usize| {
        crate::geometry::boxes_within(loop_boxes[i].as_ref(), boxes[k].as_ref(), reach)
            && crate::geometry::polylines_within(&loops[i].points, &pool[k].points, reach)
    };
    // ready[k]: loop strands laid before piece k may be (its last near one, plus one).
    let ready: Vec<usize> = (0..pool.len())
        .map(|k| {
            (0..loops.len())
                .rev()
                .find(|&i| near_loop(i, k))
                .map_or(first, |i| (i + 1).max(first))
        })
        .collect();
    // The strands of the pool each one leans on.
    let leans: Vec<Vec<usize>> = (0..pool.len())
        .map(|k| {
            (0..pool.len())
                .filter(|&j| {
                    rank(&pool[j]) < rank(&pool[k])
                        && crate::geometry::boxes_within(
                            boxes[j].as_ref(),
                            boxes[k].as_ref(),
                            reach,
                        )
                        && crate::geometry::polylines_within(
                            &pool[j].points,
                            &pool[k].points,
                            reach,
                        )
                })
                .collect()
        })
        .collect();
    let mut laid = vec![false; pool.len()];
    let mut out: Vec<Strand> = Vec::with_capacity(loops.len() + pool.len());
    // The points of each closed piece a seam may take, found once it is free to go.
    let mut seams: Vec<Option<Polyline>> = vec![None; pool.len()];
    // Lays, from `at`, the pieces free to go (`free`) whose detour from `at` to `next` costs
    // at most [`FINISH_DETOUR`] widths more than `base`, cheapest first.
    let mut lay = |out: &mut Vec<Strand>,
                   laid: &mut Vec<bool>,
                   mut at: [f64; 2],
                   next: Option<[f64; 2]>,
                   mut base: f64,
                   free: &dyn Fn(usize) -> bool| {
        let mut count = 0usize;
        loop {
            let mut best: Option<(f64, usize, bool, [f64; 2])> = None;
            for k in (0..pool.len()).filter(|&k| !laid[k] && free(k)) {
                if leans[k].iter().any(|&j| !laid[j]) {
                    continue;
                }
                let p = &pool[k].points;
                let closed = is_closed(p);
                for rev in [false, true] {
                    if closed && rev {
                        continue;
                    }
                    let (s, e) = if closed {
                        // Its seam on a point the strands laid hold (all it leans on is
                        // laid by now): a ring begun over air leaves its first bead
                        // dangling there.
                        let seams = seams[k].get_or_insert_with(|| {
                            let on: Vec<[f64; 2]> = p
                                .iter()
                                .copied()
                                .filter(|&v| held(out, below, v, pool[k].width))
                                .collect();
                            if on.is_empty() {
                                p.clone()
                            } else {
                                on
                            }
                        });
                        let s = seams
                            .iter()
                            .copied()
                            .min_by(|a, b| dist2(*a, at).total_cmp(&dist2(*b, at)))
                            .unwrap_or(p[0]);
                        (s, s)
                    } else if rev {
                        (p[p.len() - 1], p[0])
                    } else {
                        (p[0], p[p.len() - 1])
                    };
                    let cost =
                        dist2(at, s).sqrt() + next.map_or(0.0, |n| dist2(e, n).sqrt()) - base;
                    if best.is_none_or(|b| cost < b.0) {
                        best = Some((cost, k, rev, s));
                    }
                }
            }
            let Some((_, k, rev, seam)) =
                best.filter(|b| next.is_none() || b.0 <= FINISH_DETOUR * w)
            else {
                break;
            };
            let mut points = pool[k].points.clone();
            if is_closed(&points) {
                start_nearest(&mut points, seam);
            } else if rev {
                points.reverse();
            }
            at = points[points.len() - 1];
            out.push(Strand {
                points,
                ..pool[k].clone()
            });
            laid[k] = true;
            count += 1;
            base = next.map_or(0.0, |n| dist2(at, n).sqrt());
        }
        count
    };
    for (i, strand) in loops.iter().enumerate() {
        // Where the pieces that lean on this strand last are free to go along it.
        let cum = running_lengths(&strand.points);
        let total = cum[cum.len() - 1];
        let mut cuts: Vec<(f64, usize)> = (0..pool.len())
            .filter(|&k| !laid[k] && ready[k] == i + 1 && i >= first)
            .filter_map(|k| {
                let t = last_near(&strand.points, &cum, &pool[k].points, reach, w / 4.0)?;
                (t >= w && t <= total - w).then_some((t, k))
            })
            .collect();
        cuts.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut from = 0.0;
        let mut passed: Vec<usize> = Vec::new();
        for &(t, k) in &cuts {
            passed.push(k);
            if t < from + w {
                continue;
            }
            let here = point_along(&strand.points, &cum, t);
            // A cut leaves two ends there: only where a strand laid before holds the bead
            // (a cut over air left its end dangling: 1.1 mm in air where the loop had
            // bridged whole).
            if !held(&out, below, here, strand.width) {
                continue;
            }
            let free = |j: usize| ready[j] <= i || passed.contains(&j);
            let mut pieces_out = Vec::new();
            lay(&mut pieces_out, &mut laid, here, Some(here), 0.0, &free);
            if !pieces_out.is_empty() {
                out.push(Strand {
                    points: sub_polyline(&strand.points, &cum, from, t),
                    ..strand.clone()
                });
                out.extend(pieces_out);
                from = t;
            }
        }
        out.push(Strand {
            points: if from > 0.0 {
                sub_polyline(&strand.points, &cum, from, total)
            } else {
                strand.points.clone()
            },
            ..strand.clone()
        });
        let Some(next) = loops.get(i + 1) else { break };
        let at = strand.points[strand.points.len() - 1];
        let next_at = next.points[0];
        // The hop to the next loop costs nothing where the writer joins it by a connector.
        let joined = strand.kind == StrandKind::Loop
            && next.kind == StrandKind::Loop
            && (next.loop_index == strand.loop_index || next.loop_index == strand.loop_index + 1)
            && dist2(at, next_at).sqrt() <= 2.0 * strand.width.min(next.width);
        let base = if joined {
            0.0
        } else {
            dist2(at, next_at).sqrt()
        };
        lay(&mut out, &mut laid, at, Some(next_at), base, &|j| {
            ready[j] <= i + 1
        });
    }
    // The rest after the loops, nearest first, each once all it leans on is laid.
    let at = out.last().and_then(|s| s.points.last().copied())?;
    lay(&mut out, &mut laid, at, None, 0.0, &|_| true);
    Some(out)
}

/// Travel between the strands of a plan, less the hops from a loop to itself or the next
/// one within two widths (the writer lays those as extruded connectors, [`crate::emit`]).
fn hop_travel(strands: &[Strand]) -> f64 {
    strands
        .windows(2)
        .filter_map(|p| {
            let (a, b) = (p[0].points.last()?, p[1].points.first()?);
            let d = dist2(*a, *b).sqrt();
            let joined = p[0].kind == StrandKind::Loop
                && p[1].kind == StrandKind::Loop
                && (p[1].loop_index == p[0].loop_index || p[1].loop_index == p[0].loop_index + 1)
                && d <= 2.0 * p[0].width.min(p[1].width);
            (!joined).then_some(d)
        })
        .sum()
}

/// The end of `piece` farther from `from` (where it ends when laid from the nearer one).
fn far_end(piece: &Polyline, from: [f64; 2]) -> [f64; 2] {
    let (a, b) = (piece[0], piece[piece.len() - 1]);
    if dist2(a, from) <= dist2(b, from) {
        b
    } else {
        a
    }
}

/// Running lengths along the polyline `p` (0 at its start).
fn running_lengths(p: &Polyline) -> Vec<f64> {
    std::iter::once(0.0)
        .chain(p.windows(2).scan(0.0, |acc, w| {
            *acc += dist2(w[0], w[1]).sqrt();
            Some(*acc)
        }))
        .collect()
}

/// The point `t` mm along the polyline `p` whose running lengths are `cum`.
fn point_along(p: &Polyline, cum: &[f64], t: f64) -> [f64; 2] {
    let i = cum.partition_point(|&c| c <= t).clamp(1, p.len() - 1);
    let (c0, c1) = (cum[i - 1], cum[i]);
    let f = if c1 > c0 {
        ((t - c0) / (c1 - c0)).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let (a, b) = (p[i - 1], p[i]);
    [a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1])]
}

/// The stretch of the polyline `p` (running lengths `cum`) from `t0` to `t1` mm along it.
fn sub_polyline(p: &Polyline, cum: &[f64], t0: f64, t1: f64) -> Polyline {
    let mut out = vec![point_along(p, cum, t0)];
    out.extend(
        (0..p.len())
            .filter(|&i| cum[i] > t0 + 1e-9 && cum[i] < t1 - 1e-9)
            .map(|i| p[i]),
    );
    out.push(point_along(p, cum, t1));
    out
}

/// `strands` in the same groups (kind and loop) and group order, each group re-ordered from
/// `at` (see [`order`]): a gradual overhang's block is planned before the writer knows
/// where the nozzle will be, and starts there once it does.
pub fn reorder_from(strands: &[Strand], mut at: [f64; 2]) -> Vec<Strand> {
    let start = at;
    let mut out: Vec<Strand> = Vec::with_capacity(strands.len());
    let mut i = 0;
    while i < strands.len() {
        let (kind, index, width) = (strands[i].kind, strands[i].loop_index, strands[i].width);
        let mut j = i;
        while j < strands.len() && strands[j].kind == kind && strands[j].loop_index == index {
            j += 1;
        }
        let pieces = strands[i..j].iter().map(|s| s.points.clone()).collect();
        let shape = Shape {
            kind,
            loop_index: index,
            width,
        };
        out.extend(shape.strands(pieces, 0.0, &mut at));
        i = j;
    }
    sequence(&mut out, start);
    out
}

/// The contour's pieces (width `w`) and the moved perimeter's (width `we`) in one
/// nearest-first order from `at`, a perimeter piece only once every contour piece beside it
/// is printed (it leans on them). A region whose outline meets it at two far ends (the
/// strip at an arch's crown) so finishes one end, then the other, instead of crossing to
/// the far end for the contour and back again for the perimeter.
fn finish_order(
    contour: Vec<Polyline>,
    perimeter: Vec<Polyline>,
    w: f64,
    we: f64,
    at: &mut [f64; 2],
) -> Vec<Strand> {
    let reach = w + we;
    let mut todo: Vec<(StrandKind, Polyline, [f64; 4])> = contour
        .into_iter()
        .filter(|p| polyline_length(p) >= w)
        .map(|p| (StrandKind::Contour, p))
        .chain(
            perimeter
                .into_iter()
                .filter(|p| polyline_length(p) >= we)
                .map(|p| (StrandKind::Perimeter, p)),
        )
        .map(|(k, p)| {
            // Pieces are at least a width long: never empty.
            let b = crate::geometry::points_box(&p)
                .map_or([0.0; 4], |r| [r.min().x, r.min().y, r.max().x, r.max().y]);
            (k, p, b)
        })
        .collect();
    let meets = |a: &[f64; 4], b: &[f64; 4]| {
        a[0] - reach <= b[2] && b[0] <= a[2] + reach && a[1] - reach <= b[3] && b[1] <= a[3] + reach
    };
    let mut out = Vec::with_capacity(todo.len());
    while !todo.is_empty() {
        let ready = |i: usize| {
            todo[i].0 == StrandKind::Contour
                || !todo
                    .iter()
                    .any(|c| c.0 == StrandKind::Contour && meets(&c.2, &todo[i].2))
        };
        // A contour piece is always ready, so some piece is.
        let next = (0..todo.len())
            .filter(|&i| ready(i))
            .min_by(|&i, &j| {
                start_distance2(&todo[i].1, *at).total_cmp(&start_distance2(&todo[j].1, *at))
            })
            .unwrap_or(0);
        let (kind, mut points, _) = todo.swap_remove(next);
        start_nearest(&mut points, *at);
        *at = points[points.len() - 1];
        out.push(Strand {
            kind,
            loop_index: 0,
            points,
            width: if kind == StrandKind::Perimeter { we } else { w },
        });
    }
    out
}

/// What a set of pieces becomes: strands of one kind, loop number and width.
struct Shape {
    kind: StrandKind,
    loop_index: usize,
    width: f64,
}

impl Shape {
    fn perimeter(width: f64) -> Shape {
        Shape {
            kind: StrandKind::Perimeter,
            loop_index: 0,
            width,
        }
    }

    /// The pieces at least `min_len` long, ordered from `at` (see [`order`]), as strands.
    fn strands(&self, pieces: Vec<Polyline>, min_len: f64, at: &mut [f64; 2]) -> Vec<Strand> {
        let pieces = pieces
            .into_iter()
            .filter(|p| polyline_length(p) >= min_len)
            .collect();
        order(pieces, at)
            .into_iter()
            .map(|points| Strand {
                kind: self.kind,
                loop_index: self.loop_index,
                points,
                width: self.width,
            })
            .collect()
    }
}

/// Where a half-width loop under a perimeter gives way to the full one: a ring across walls
/// of different slopes (a ramp's steps side by side, an egg's ends and sides) lies near the
/// perimeter on the steep ones and well inside it on the flatter ones, where a half-width
/// loop leaves the perimeter hanging past its edge (a 55 degree step beside a 45 degree one
/// by Cura: 9.3 mm in air on one layer). `ring`: the full loop's ring; its stretches inside
/// `full_room` (the perimeter's area drawn in by [`HALF_LOOP_AT`] widths) longer than
/// [`MIXED_RUN`] are returned as full loops, and `half` without what lies beside them.
fn full_stretches(
    ring: &[Polyline],
    half: Vec<Polyline>,
    full_room: &MultiPolygon<f64>,
    w: f64,
) -> (Vec<Polyline>, Vec<Polyline>) {
    let full: Vec<Polyline> = clip_lines(ring, full_room, true)
        .into_iter()
        .filter(|p| polyline_length(p) >= MIXED_RUN)
        .collect();
    if full.is_empty() {
        return (full, half);
    }
    let mask =
        crate::geometry::area::Strands::of_lines(full.iter().map(|p| (&p[..], MIXED_MASK * w)))
            .buffer();
    let half = clip_lines(&half, &mask, false);
    (full, half)
}

/// `rect` grown by `margin` on every side, as a polygon.
fn boxed(rect: &geo::Rect<f64>, margin: f64) -> MultiPolygon<f64> {
    let (lo, hi) = (rect.min(), rect.max());
    MultiPolygon::new(vec![geo::Rect::new(
        geo::coord! {x: lo.x - margin, y: lo.y - margin},
        geo::coord! {x: hi.x + margin, y: hi.y + margin},
    )
    .to_polygon()])
}

fn dist2(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)
}

/// Squared distance from `at` to where `p` can start: its nearer end, or for a closed ring
/// its nearest vertex.
fn start_distance2(p: &Polyline, at: [f64; 2]) -> f64 {
    if is_closed(p) {
        p.iter()
            .map(|q| dist2(*q, at))
            .fold(f64::INFINITY, f64::min)
    } else {
        dist2(p[0], at).min(dist2(p[p.len() - 1], at))
    }
}

/// Orders pieces greedily, each starting at its end (or, for a closed ring, its vertex)
/// nearest to where the previous one ended. Updates `at` to the last end.
///
/// Greedy from `at` alone goes round a ring of pieces the nearer way and comes back across
/// for the ones it left behind: with few pieces (a gradual overhang's ring cut where the
/// wall below already holds it), every piece is tried first, each way round, and the order
/// with the least travel (from `at` on) is kept.
fn order(pieces: Vec<Polyline>, at: &mut [f64; 2]) -> Vec<Polyline> {
    const TRY_ALL: usize = 24;
    let n = pieces.len();
    if n <= 1 || n > TRY_ALL || pieces.iter().any(is_closed) {
        return greedy(pieces, at);
    }
    let mut best: Option<(f64, Vec<Polyline>, [f64; 2])> = None;
    for first in 0..n {
        for reverse in [false, true] {
            let mut rest = pieces.clone();
            let mut p = rest.swap_remove(first);
            if reverse {
                p.reverse();
            }
            let mut travel = dist2(*at, p[0]).sqrt();
            let mut end = p[p.len() - 1];
            let mut seq = vec![p];
            for q in greedy(rest, &mut end.clone()) {
                travel += dist2(end, q[0]).sqrt();
                end = q[q.len() - 1];
                seq.push(q);
            }
            if best.as_ref().is_none_or(|b| travel < b.0 - 1e-9) {
                best = Some((travel, seq, end));
            }
        }
    }
    match best {
        Some((_, seq, end)) => {
            *at = end;
            seq
        }
        None => greedy(pieces, at),
    }
}

/// [`order`] by nearest next piece only.
fn greedy(mut pieces: Vec<Polyline>, at: &mut [f64; 2]) -> Vec<Polyline> {
    let mut out = Vec::with_capacity(pieces.len());
    while !pieces.is_empty() {
        let mut best = (f64::INFINITY, 0usize);
        for (i, p) in pieces.iter().enumerate() {
            let d = start_distance2(p, *at);
            if d < best.0 {
                best = (d, i);
            }
        }
        let mut p = pieces.swap_remove(best.1);
        start_nearest(&mut p, *at);
        *at = p[p.len() - 1];
        out.push(p);
    }
    out
}

/// Makes `p` start at its end (or, for a closed ring, its vertex) nearest `at`.
fn start_nearest(p: &mut Polyline, at: [f64; 2]) {
    if is_closed(p) {
        p.pop();
        let i = p
            .iter()
            .enumerate()
            .min_by(|a, b| dist2(*a.1, at).total_cmp(&dist2(*b.1, at)))
            .map(|(i, _)| i)
            .unwrap_or(0);
        p.rotate_left(i);
        p.push(p[0]);
    } else if dist2(p[p.len() - 1], at) < dist2(p[0], at) {
        p.reverse();
    }
}

/// How far along a closed loop its seam moves from the previous loop's: as far as keeps
/// the hop there (`step` out, this along) within two widths, the longest hop the writer
/// makes without retracting inside a block; 0.77 mm at 0.45 mm width and overlap 0.4. The
/// seams then part by more than a width from ring to ring.
fn seam_stagger(w: f64, step: f64) -> f64 {
    0.9 * (4.0 * w * w - step * step).max(0.0).sqrt()
}

/// Rings shorter than this many staggers keep their seam where they start: the extra hop
/// would cost them more than a tenth of their length in travel.
const STAGGER_MIN_RINGS: f64 = 10.0;

/// Moves the start (and end) of the closed ring `p` by `d` mm along it.
fn stagger_seam(p: &mut Polyline, d: f64) {
    if d <= 0.0 || polyline_length(p) < STAGGER_MIN_RINGS * d {
        return;
    }
    let mut acc = 0.0;
    for i in 0..p.len() - 1 {
        let l = dist2(p[i], p[i + 1]).sqrt();
        if acc + l > d {
            cut_ring(p, i, (d - acc) / l);
            return;
        }
        acc += l;
    }
}

/// Makes the closed ring `p` start at its point nearest `at`.
fn start_at_nearest_point(p: &mut Polyline, at: [f64; 2]) {
    let mut best = (f64::INFINITY, 0usize, 0.0);
    for i in 0..p.len() - 1 {
        let (t, q) = crate::geometry::nearest_on_segment(at, p[i], p[i + 1]);
        let d = dist2(q, at);
        if d < best.0 {
            best = (d, i, t);
        }
    }
    cut_ring(p, best.1, best.2);
}

/// Makes the closed ring `p` start (and end) at share `t` of its segment `i`.
fn cut_ring(p: &mut Polyline, i: usize, t: f64) {
    let (a, b) = (p[i], p[i + 1]);
    if t >= 1.0 - 1e-9 {
        if i + 1 < p.len() - 1 {
            cut_ring(p, i + 1, 0.0);
        }
        return;
    }
    let cut = [a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t];
    // The ring from the cut round to the cut: [cut, b, ..., last = first, ..., a, cut].
    let mut ring: Polyline = Vec::with_capacity(p.len() + 1);
    ring.push(cut);
    ring.extend_from_slice(&p[i + 1..p.len() - 1]);
    ring.extend_from_slice(&p[..i]);
    if t > 1e-9 {
        ring.push(a);
    }
    ring.push(cut);
    *p = ring;
}

/// Most strands [`sequence`] orders exactly: its table has 2^n x n x 2 entries.
const MAX_SEQUENCED: usize = 12;

/// A plan's strands laid in the order and directions of least travel from `start`:
/// [`orient`], then, for a plan of at most [`MAX_SEQUENCED`] strands, [`sequence`].
fn arrange(strands: &mut Vec<Strand>, start: [f64; 2]) {
    orient(strands, start);
    sequence(strands, start);
}

/// Travel (in widths) a cut in a gradual overhang's perimeter must save to be made
/// ([`split_perimeters`]): each cut is one more seam in the part's outer wall.
const PERIMETER_CUT_SAVES: f64 = 4.0;

/// Most sample points times points of the strands they are measured against that
/// [`split_perimeters`] spends on one plan.
const PERIMETER_CUT_WORK: usize = 4_000_000;

/// A small plan's open contour and perimeter strands cut where the strands they must follow
/// change, so that [`sequence`] can lay each stretch as the nozzle passes it. A hull's bow
/// (a gradual overhang): loop 1 along both sides, loop 2 at the bow only, the perimeter along
/// both sides; laid whole after loop 2, the perimeter began at one side's far end, two hops
/// the length of a side (13.6 mm of travel for 32.9 mm of loops); cut, one side's perimeter
/// follows loop 1 there, loop 2 follows it, and the rest of the perimeter loop 2. A stretch
/// leans on every strand of an earlier kind (loops, then the contour) within two widths of
/// it, as in [`sequence`], so it is still laid after each of them. Stretches laid one after
/// the other are joined again; the cuts are kept only where each saves
/// [`PERIMETER_CUT_SAVES`] widths of travel between strands.
fn split_perimeters(strands: &mut Vec<Strand>, start: [f64; 2]) {
    let n = strands.len();
    if !(2..MAX_SEQUENCED).contains(&n) {
        return;
    }
    let open = |s: &Strand| s.points.len() >= 2 && !is_closed(&s.points);
    // What a stretch may lean on: every strand of a kind laid before its own (loops before
    // the contour, both before the perimeter).
    let lines: Vec<(usize, f64)> = strands
        .iter()
        .enumerate()
        .filter(|(_, s)| s.kind != StrandKind::Perimeter && s.points.len() >= 2)
        .map(|(i, s)| (i, s.width))
        .collect();
    if lines.is_empty() {
        return;
    }
    let loop_points: usize = lines.iter().map(|&(i, _)| strands[i].points.len()).sum();
    let near = |q: [f64; 2], j: usize, g: f64| {
        strands[j].points.windows(2).any(|seg| {
            let (_, m) = crate::geometry::nearest_on_segment(q, seg[0], seg[1]);
            dist2(q, m) <= g * g
        })
    };
    let mut out: Vec<Strand> = Vec::with_capacity(MAX_SEQUENCED);
    let mut cut = false;
    // Sample-to-point distances measured so far, for the whole plan.
    let mut work = 0usize;
    for (i, s) in strands.iter().enumerate() {
        if s.kind == StrandKind::Loop || !open(s) {
            out.push(s.clone());
            continue;
        }
        let cum = running_lengths(&s.points);
        let total = cum[cum.len() - 1];
        let spacing = s.width / 4.0;
        let samples = (total / spacing).ceil() as usize + 1;
        work = work.saturating_add(samples.saturating_mul(loop_points));
        if work > PERIMETER_CUT_WORK || total < 4.0 * s.width {
            out.push(s.clone());
            continue;
        }
        // The loops each sample lies beside (a bit set over `lines`), measured a sample's
        // spacing farther, so that all the stretch between two samples counts.
        let mask = |t: f64| -> u32 {
            let q = point_along(&s.points, &cum, t);
            lines
                .iter()
                .enumerate()
                .filter(|&(_, &(j, _))| (strands[j].kind as usize) < (s.kind as usize))
                .filter(|&(_, &(j, wj))| near(q, j, 2.0 * s.width.max(wj) + spacing))
                .fold(0u32, |m, (b, _)| m | 1 << b)
        };
        // Runs of equal sets: (from mm, set); a run ends where the next set is first seen.
        let mut runs: Vec<(f64, u32)> = Vec::new();
        for k in 0..samples {
            let t = (k as f64 * spacing).min(total);
            let m = mask(t);
            if runs.last().is_none_or(|r| r.1 != m) {
                runs.push((if runs.is_empty() { 0.0 } else { t }, m));
            }
        }
        // Stretch `k` joined to the neighbour whose strands it shares most of (the one
        // before on a tie), leaning on the strands of both; neighbours with equal sets are
        // one stretch.
        let merge = |runs: &mut Vec<(f64, u32)>, k: usize| {
            let share = |o: usize| (runs[o].1 & runs[k].1).count_ones();
            let into = if k == 0 {
                1
            } else if k + 1 < runs.len() && share(k + 1) > share(k - 1) {
                k + 1
            } else {
                k - 1
            };
            runs[into].1 |= runs[k].1;
            if into > k {
                runs[into].0 = runs[k].0;
            }
            runs.remove(k);
            runs.dedup_by(|b, a| a.1 == b.1);
        };
        let length =
            |runs: &[(f64, u32)], k: usize| runs.get(k + 1).map_or(total, |r| r.0) - runs[k].0;
        // Stretches shorter than two widths go first; then the shortest until the plan fits
        // the sequencer.
        while let Some(k) =
            (0..runs.len()).find(|&k| runs.len() > 1 && length(&runs, k) < 2.0 * s.width)
        {
            merge(&mut runs, k);
        }
        while runs.len() > 1 && out.len() + runs.len() + (n - i - 1) > MAX_SEQUENCED {
            let k = (0..runs.len())
                .min_by(|&a, &b| length(&runs, a).total_cmp(&length(&runs, b)))
                .unwrap_or(0);
            merge(&mut runs, k);
        }
        if runs.len() < 2 || out.len() + runs.len() + (n - i - 1) > MAX_SEQUENCED {
            out.push(s.clone());
            continue;
        }
        cut = true;
        for (r, &(from, _)) in runs.iter().enumerate() {
            let to = runs.get(r + 1).map_or(total, |x| x.0);
            out.push(Strand {
                points: sub_polyline(&s.points, &cum, from, to),
                ..s.clone()
            });
        }
    }
    if !cut {
        return;
    }
    let before = travel_of(strands, start);
    let pieces = |v: &[Strand]| v.iter().filter(|s| s.kind != StrandKind::Loop).count();
    let was = pieces(strands);
    arrange(&mut out, start);
    // Stretches laid end to end are one strand again.
    let mut joined: Vec<Strand> = Vec::with_capacity(out.len());
    for s in out {
        match joined.last_mut() {
            Some(last)
                if last.kind != StrandKind::Loop
                    && s.kind == last.kind
                    && last.points.last() == s.points.first() =>
            {
                last.points.extend_from_slice(&s.points[1..]);
            }
            _ => joined.push(s),
        }
    }
    let cuts = pieces(&joined).saturating_sub(was);
    let w = strands.iter().map(|s| s.width).fold(0.0, f64::max);
    // The hops between strands (the travel inside the region) must fall by the cuts' due,
    // and the way in from `start` must not eat the saving.
    let inner = |v: &[Strand]| v.first().map_or(0.0, |f| travel_of(v, f.points[0]));
    let saved = inner(strands) - inner(&joined);
    if saved > cuts as f64 * PERIMETER_CUT_SAVES * w && travel_of(&joined, start) < before - 1e-6 {
        *strands = joined;
    }
}

/// Travel from `start` through `strands` as laid.
fn travel_of(strands: &[Strand], start: [f64; 2]) -> f64 {
    let mut at = start;
    let mut sum = 0.0;
    for s in strands {
        if let (Some(&a), Some(&b)) = (s.points.first(), s.points.last()) {
            sum += dist2(at, a).sqrt();
            at = b;
        }
    }
    sum
}

/// Re-orders a plan of few strands for the least travel from `start`, exactly (a table over
/// the sets of strands laid, the last one and its direction). Pieces of one rank (one loop,
/// the contour, the perimeter) go in any order and either way round; two strands of
/// different ranks that lie beside each other (within two widths) keep the order the
/// plan gave them, since the later one leans on the earlier. The greedy order takes the
/// nearest free piece and cannot see that a piece laid the other way, or one left for
/// later, saves a crossing: a hull's bow region, its loop in two arms along the sides,
/// crossed from arm to arm and back (17.1 mm of travel for 60.3 mm of loops). The plan's
/// order is kept unless the new one travels less.
fn sequence(strands: &mut Vec<Strand>, start: [f64; 2]) {
    let n = strands.len();
    if !(2..=MAX_SEQUENCED).contains(&n) || strands.iter().any(|s| s.points.is_empty()) {
        return;
    }
    let rank = |s: &Strand| (s.kind as usize, s.loop_index);
    let boxes: Vec<Option<geo::Rect<f64>>> = strands
        .iter()
        .map(|s| crate::geometry::points_box(&s.points))
        .collect();
    let lines: Vec<geo::LineString<f64>> = strands
        .iter()
        .map(|s| {
            s.points
                .iter()
                .map(|p| geo::coord! { x: p[0], y: p[1] })
                .collect()
        })
        .collect();
    let near = |j: usize, k: usize| {
        use geo::{Distance, Euclidean};
        let g = 2.0 * strands[j].width.max(strands[k].width);
        crate::geometry::boxes_within(boxes[j].as_ref(), boxes[k].as_ref(), g)
            && Euclidean.distance(&lines[j], &lines[k]) <= g
    };
    // after[k]: the strands that must be laid before strand k.
    let after: Vec<u32> = (0..n)
        .map(|k| {
            (0..k)
                .filter(|&j| rank(&strands[j]) != rank(&strands[k]) && near(j, k))
                .fold(0u32, |m, j| m | 1 << j)
        })
        .collect();
    let open: Vec<bool> = strands
        .iter()
        .map(|s| s.points.len() >= 2 && !is_closed(&s.points))
        .collect();
    let ends = |k: usize, o: usize| {
        let p = &strands[k].points;
        let (a, b) = (p[0], p[p.len() - 1]);
        if o == 1 {
            (b, a)
        } else {
            (a, b)
        }
    };
    // cost[(mask * n + last) * 2 + o], and the (last, o) before it.
    let full = (1usize << n) - 1;
    let at = |mask: usize, last: usize, o: usize| (mask * n + last) * 2 + o;
    let mut cost = vec![f64::INFINITY; (full + 1) * n * 2];
    let mut from = vec![(u8::MAX, 0u8); (full + 1) * n * 2];
    for k in (0..n).filter(|&k| after[k] == 0) {
        for o in 0..1 + open[k] as usize {
            cost[at(1 << k, k, o)] = dist2(start, ends(k, o).0).sqrt();
        }
    }
    for mask in 1..=full {
        for last in (0..n).filter(|&l| mask & 1 << l != 0) {
            for lo in 0..2 {
                let c = cost[at(mask, last, lo)];
                if !c.is_finite() {
                    continue;
                }
                let end = ends(last, lo).1;
                for k in (0..n).filter(|&k| mask & 1 << k == 0 && after[k] as usize & !mask == 0) {
                    let next = mask | 1 << k;
                    for o in 0..1 + open[k] as usize {
                        let v = c + dist2(end, ends(k, o).0).sqrt();
                        if v < cost[at(next, k, o)] {
                            cost[at(next, k, o)] = v;
                            from[at(next, k, o)] = (last as u8, lo as u8);
                        }
                    }
                }
            }
        }
    }
    let Some((best, mut last, mut o)) = (0..n)
        .flat_map(|l| [(l, 0), (l, 1)])
        .map(|(l, o)| (cost[at(full, l, o)], l, o))
        .min_by(|a, b| a.0.total_cmp(&b.0))
    else {
        return;
    };
    if !best.is_finite() || best >= travel_of(strands, start) - 1e-6 {
        return;
    }
    let mut order: Vec<(usize, usize)> = Vec::with_capacity(n);
    let mut mask = full;
    loop {
        order.push((last, o));
        let (pl, po) = from[at(mask, last, o)];
        mask &= !(1 << last);
        if pl == u8::MAX {
            break;
        }
        (last, o) = (pl as usize, po as usize);
    }
    order.reverse();
    let mut taken: Vec<Option<Strand>> = strands.drain(..).map(Some).collect();
    for (k, o) in order {
        if let Some(mut s) = taken[k].take() {
            if o == 1 {
                s.points.reverse();
            }
            strands.push(s);
        }
    }
}

/// Turns the open strands of a plan end for end where that shortens the travel between
/// them, keeping their order (each strand rests on those before it, whichever way it is
/// laid): the order is chosen a group at a time from where the nozzle is, so the last
/// piece of one loop could end at the far side of the next loop's nearer end (a hook's
/// short rings: 4.0 mm of travel for 11.8 mm of loops, 3.0 turned). Closed strands keep
/// their seams. Exact over the whole sequence: two states per strand.
fn orient(strands: &mut [Strand], start: [f64; 2]) {
    if strands.len() < 2 {
        return;
    }
    let ends = |s: &Strand, reversed: bool| -> ([f64; 2], [f64; 2]) {
        let (a, b) = (s.points[0], s.points[s.points.len() - 1]);
        if reversed {
            (b, a)
        } else {
            (a, b)
        }
    };
    let open = |s: &Strand| s.points.len() >= 2 && !is_closed(&s.points);
    // cost[o]: least travel up to this strand laid forward (0) or reversed (1); how[i][o]:
    // the orientation of strand i - 1 that gave it.
    let mut how: Vec<[bool; 2]> = Vec::with_capacity(strands.len());
    let mut cost = [0.0f64; 2];
    let mut prev: Option<&Strand> = None;
    for s in strands.iter() {
        if s.points.is_empty() {
            return;
        }
        let mut next = [f64::INFINITY; 2];
        let mut from = [false; 2];
        for (o, slot) in next.iter_mut().enumerate() {
            if o == 1 && !open(s) {
                continue;
            }
            let begin = ends(s, o == 1).0;
            match prev {
                None => *slot = dist2(start, begin).sqrt(),
                Some(p) => {
                    for po in [false, true] {
                        if po && !open(p) {
                            continue;
                        }
                        let c = cost[po as usize] + dist2(ends(p, po).1, begin).sqrt();
                        if c < *slot {
                            *slot = c;
                            from[o] = po;
                        }
                    }
                }
            }
        }
        how.push(from);
        cost = next;
        prev = Some(s);
    }
    // Ties keep each strand as it was ordered.
    let mut o = cost[1] + 1e-9 < cost[0];
    for i in (0..strands.len()).rev() {
        if o {
            strands[i].points.reverse();
        }
        o = how[i][o as usize];
    }
}

fn is_closed(p: &Polyline) -> bool {
    p.len() > 3 && dist2(p[0], p[p.len() - 1]) < 1e-12
}

#[cfg(test)]
pub(crate) mod testutil {
    use crate::geometry::{Region, RegionKind};
    use geo::Polygon;

    /// An overhang region on layer 1 reaching `max_distance` from what holds it.
    pub fn overhang(polygon: Polygon<f64>, max_distance: f64) -> Region {
        Region {
            layer: 1,
            z: 0.4,
            height: 0.2,
            kind: RegionKind::Overhang,
            area: geo::Area::unsigned_area(&polygon),
            polygon,
            max_distance,
            anchored_length: 0.0,
            anchors: 1,
            object: None,
            extrusions: Vec::new(),
        }
    }
}

#[cfg(test)]
mod tests {
    //! The planner on literal polygons, judged geometrically: every strand inside the zone,
    //! consecutive loops `step` apart (so each bites `overlap x w` into the one before, and
    //! loop 1 into the wall below), the zone covered.
    use super::*;
    use crate::geometry::testutil::{mp, rect};
    use geo::{Contains, Polygon};

    const W: f64 = 0.45;

    #[test]
    fn a_short_piece_goes_back_in_where_the_next_loop_would_rest_on_nothing() {
        // Rungs across a bar 0.4 mm wide, a step (0.27 mm) apart, from a wall at x = 0:
        // loop 0's rung at the bar's end is short (0.2 mm, kept aside), loop 1's and 2's
        // are whole. Another short piece of loop 0 lies far off; one of loop 1 lies by a
        // rung of loop 0 already.
        let step = 0.27;
        let rung = |x: f64, y0: f64, y1: f64| vec![[x, y0], [x, y1]];
        let mut loops = vec![
            vec![rung(5.0, 10.0, 10.4)],
            vec![rung(step, 0.0, 0.4), rung(5.0 + step, 10.0, 10.4)],
            vec![rung(2.0 * step, 0.0, 0.4)],
        ];
        let shorts = vec![
            (0, rung(0.0, 0.1, 0.3)),
            (0, rung(30.0, 0.0, 0.2)),
            (1, rung(5.0 + step, 10.5, 10.7)),
        ];
        keep_needed_shorts(&mut loops, shorts, step);
        assert_eq!(loops[0].len(), 2, "{:?}", loops[0]);
        assert_eq!(loops[0][1], rung(0.0, 0.1, 0.3));
        assert_eq!(
            loops[1].len(),
            2,
            "loop 1's rungs all rest on loop 0's: {:?}",
            loops[1]
        );
        assert_eq!(loops[2].len(), 1);
    }

    #[test]
    fn gaps_smaller_than_a_bead_are_no_holes_to_plan_round() {
        // A 10 x 10 area with a 0.3 mm gap (where two walls meet), a 1 mm hole and a
        // 0.3 x 3 mm slot: the gap is filled, the hole and the slot stay.
        let hole = |x0: f64, y0: f64, x1: f64, y1: f64| rect(x0, y0, x1, y1).exterior().clone();
        let area = mp(vec![Polygon::new(
            rect(0.0, 0.0, 10.0, 10.0).exterior().clone(),
            vec![
                hole(1.0, 1.0, 1.3, 1.3),
                hole(4.0, 4.0, 5.0, 5.0),
                hole(7.0, 2.0, 7.3, 5.0),
            ],
        )]);
        let out = without_specks(area, W);
        let holes: Vec<f64> = out.0[0]
            .interiors()
            .iter()
            .map(|h| Polygon::new(h.clone(), Vec::new()).unsigned_area())
            .collect();
        assert_eq!(holes.len(), 2, "{holes:?}");
        assert!((holes[0] - 1.0).abs() < 1e-9 && (holes[1] - 0.9).abs() < 1e-9);
        assert!((out.unsigned_area() - (100.0 - 1.9)).abs() < 1e-9);
    }

    #[test]
    fn strands_are_turned_end_for_end_to_shorten_the_travel_in_their_order() {
        let strand = |pts: &[[f64; 2]]| Strand {
            kind: StrandKind::Loop,
            loop_index: 1,
            points: pts.to_vec(),
            width: 0.45,
        };
        let travel = |v: &[Strand], start: [f64; 2]| {
            let mut at = start;
            let mut t = 0.0;
            for s in v {
                t += dist2(at, s.points[0]).sqrt();
                at = s.points[s.points.len() - 1];
            }
            t
        };
        // Three short arcs of a hook's ring, as the greedy order laid them: the first ends
        // at the far side of the second's nearer end, the second at the far side of the third.
        let mut v = vec![
            strand(&[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]]),
            strand(&[[3.0, 1.0], [3.0, 0.0]]),
            strand(&[[1.0, -1.0], [2.0, -1.0]]),
            // A closed ring keeps its seam.
            strand(&[[5.0, 5.0], [6.0, 5.0], [6.0, 6.0], [5.0, 5.0]]),
        ];
        let before = travel(&v, [0.0, 0.0]);
        let firsts: Vec<Vec<[f64; 2]>> = v.iter().map(|s| s.points.clone()).collect();
        orient(&mut v, [0.0, 0.0]);
        let after = travel(&v, [0.0, 0.0]);
        assert!(after < before, "{before} -> {after}");
        // The same strands in the same order, each laid one way or the other.
        for (s, f) in v.iter().zip(&firsts) {
            let mut r = f.clone();
            r.reverse();
            assert!(s.points == *f || s.points == r);
        }
        assert_eq!(v[3].points, firsts[3]);
        // The best of the 2^3 orientations of the open strands.
        let mut best = f64::INFINITY;
        for mask in 0..8u32 {
            let mut w: Vec<Strand> = firsts.iter().map(|p| strand(p)).collect();
            for (i, s) in w.iter_mut().take(3).enumerate() {
                if mask & (1 << i) != 0 {
                    s.points.reverse();
                }
            }
            best = best.min(travel(&w, [0.0, 0.0]));
        }
        assert!((after - best).abs() < 1e-9, "{after} vs {best}");
    }

    /// Every order of the strands that keeps each pair of different ranks lying beside
    /// each other as given, each open strand either way round: the least travel.
    fn least_travel_by_brute_force(v: &[Strand], start: [f64; 2]) -> f64 {
        fn permute(k: usize, idx: &mut Vec<usize>, f: &mut impl FnMut(&[usize])) {
            if k == idx.len() {
                f(idx);
                return;
            }
            for i in k..idx.len() {
                idx.swap(k, i);
                permute(k + 1, idx, f);
                idx.swap(k, i);
            }
        }
        let n = v.len();
        let mut best = f64::INFINITY;
        let mut idx: Vec<usize> = (0..n).collect();
        let beside = |a: &Strand, b: &Strand| {
            use geo::{Distance, Euclidean};
            let line = |s: &Strand| -> geo::LineString<f64> {
                s.points
                    .iter()
                    .map(|p| geo::coord! { x: p[0], y: p[1] })
                    .collect()
            };
            Euclidean.distance(&line(a), &line(b)) <= 2.0 * a.width.max(b.width)
        };
        permute(0, &mut idx, &mut |order: &[usize]| {
            let pos = |k: usize| order.iter().position(|&o| o == k).unwrap();
            for j in 0..n {
                for k in j + 1..n {
                    let ranked = (v[j].kind, v[j].loop_index) != (v[k].kind, v[k].loop_index);
                    if ranked && beside(&v[j], &v[k]) && pos(j) > pos(k) {
                        return;
                    }
                }
            }
            for flips in 0..1u32 << n {
                let w: Vec<Strand> = order
                    .iter()
                    .enumerate()
                    .map(|(i, &k)| {
                        let mut s = v[k].clone();
                        if flips & 1 << i != 0 {
                            s.points.reverse();
                        }
                        s
                    })
                    .collect();
                best = best.min(travel_of(&w, start));
            }
        });
        best
    }

    #[test]
    fn few_strands_are_laid_in_the_order_of_least_travel_keeping_what_leans_on_what() {
        // Random short strands of two loops and a perimeter in a 10 mm square (a fixed
        // linear congruential sequence), as a greedy order might give them.
        let mut rnd = crate::geometry::testutil::lcg(12345);
        for case in 0..40 {
            let n = 3 + case % 4;
            let mut v: Vec<Strand> = (0..n)
                .map(|i| {
                    let a = [10.0 * rnd(), 10.0 * rnd()];
                    let b = [a[0] + 3.0 * rnd() - 1.5, a[1] + 3.0 * rnd() - 1.5];
                    let (kind, loop_index) = match i * 3 / n {
                        0 => (StrandKind::Loop, 1),
                        1 => (StrandKind::Loop, 2),
                        _ => (StrandKind::Perimeter, 0),
                    };
                    Strand {
                        kind,
                        loop_index,
                        points: vec![a, b],
                        width: 0.45,
                    }
                })
                .collect();
            let start = [0.0, 0.0];
            let best = least_travel_by_brute_force(&v, start);
            let given = v.clone();
            arrange(&mut v, start);
            let after = travel_of(&v, start);
            assert!(
                (after - best).abs() < 1e-9,
                "case {case}: {after} vs {best}"
            );
            // The same strands, each once, either way round.
            assert_eq!(v.len(), given.len());
            for g in &given {
                let r: Vec<[f64; 2]> = g.points.iter().rev().copied().collect();
                assert!(v.iter().any(|s| s.points == g.points || s.points == r));
            }
        }
    }

    fn default_overlap() -> f64 {
        PoaSettings::default().overlap
    }

    fn seg_dist(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
        let (_, q) = crate::geometry::nearest_on_segment(p, a, b);
        (q[0] - p[0]).hypot(q[1] - p[1])
    }

    fn dist_to(p: [f64; 2], lines: &[&Polyline]) -> f64 {
        lines
            .iter()
            .flat_map(|l| l.windows(2).map(move |s| seg_dist(p, s[0], s[1])))
            .fold(f64::INFINITY, f64::min)
    }

    /// Points along a polyline every `step` mm.
    fn samples(l: &Polyline, step: f64) -> Vec<[f64; 2]> {
        let mut out = Vec::new();
        for s in l.windows(2) {
            let len = ((s[1][0] - s[0][0]).powi(2) + (s[1][1] - s[0][1]).powi(2)).sqrt();
            let n = (len / step).ceil().max(1.0) as usize;
            for i in 0..n {
                let t = i as f64 / n as f64;
                out.push([
                    s[0][0] + t * (s[1][0] - s[0][0]),
                    s[0][1] + t * (s[1][1] - s[0][1]),
                ]);
            }
        }
        out
    }

    fn region(polygon: Polygon<f64>, below: &MultiPolygon<f64>) -> Region {
        let max_distance = polygon
            .exterior()
            .points()
            .map(|p| dist_to([p.x(), p.y()], &rings(below).iter().collect::<Vec<_>>()))
            .fold(0.0, f64::max);
        testutil::overhang(polygon, max_distance)
    }

    /// [`plan`] of the region `poly` of `area` over `below`, with nothing else near it,
    /// from the origin.
    fn plan_over(
        poly: Polygon<f64>,
        below: &MultiPolygon<f64>,
        area: &MultiPolygon<f64>,
        widths: Widths,
        settings: &PoaSettings,
    ) -> Plan {
        plan(
            &region(poly, below),
            below,
            area,
            &Others::default(),
            widths,
            settings,
            [0.0, 0.0],
        )
    }

    /// Plans every region of `area` over `below` and checks the plan's geometry.
    ///
    /// Long by design: the test's geometric checks of one plan (containment, bite, coverage,
    /// supportedness), each measured next to the others.
    fn check(name: &str, below: MultiPolygon<f64>, area: MultiPolygon<f64>, overlap: f64) {
        let settings = PoaSettings {
            overlap,
            ..Default::default()
        };
        let widths = bead_widths();
        let step = (1.0 - overlap) * W;
        let uncovered = difference(&area, &below);
        assert!(!uncovered.0.is_empty(), "{name}: no region");
        for poly in &uncovered.0 {
            let plan = plan_over(poly.clone(), &below, &area, widths, &settings);
            assert!(plan.loops >= 1, "{name}: no loops");
            // 1. Every strand inside the zone (its centreline; 1 um of rounding allowed).
            let zone_grown = offset(&plan.zone, 0.001);
            for s in &plan.strands {
                for p in &s.points {
                    assert!(
                        zone_grown.contains(&geo::Point::new(p[0], p[1])),
                        "{name}: {:?} strand point {p:?} outside the zone",
                        s.kind
                    );
                }
            }
            // 2. The bite: loop k+1 lies `step` from loop k, loop 1 `step - w/2` from sectA.
            let by_loop = |k: usize| -> Vec<&Polyline> {
                plan.strands
                    .iter()
                    .filter(|s| s.kind == StrandKind::Loop && s.loop_index == k)
                    .map(|s| &s.points)
                    .collect()
            };
            let edge = rings(&below);
            let edge: Vec<&Polyline> = edge.iter().collect();
            for k in 1..=plan.loops {
                let prev = if k == 1 { edge.clone() } else { by_loop(k - 1) };
                let want = if k == 1 { step - W / 2.0 } else { step };
                let mut d: Vec<f64> = by_loop(k)
                    .iter()
                    .flat_map(|l| samples(l, 0.1))
                    .map(|p| dist_to(p, &prev))
                    // Ends of clipped loops turn along the zone's edge: measure where loops
                    // run beside each other.
                    .filter(|d| *d < 2.0 * W)
                    .collect();
                if d.len() < 5 {
                    continue;
                }
                d.sort_by(f64::total_cmp);
                let within = d.iter().filter(|x| (**x - want).abs() <= 0.02).count();
                assert!(
                    within as f64 >= 0.9 * d.len() as f64,
                    "{name}: loop {k}: {within} of {} samples {want:.3} mm from loop {} (median {:.3})",
                    d.len(),
                    k - 1,
                    d[d.len() / 2]
                );
            }
            // 3. The zone is covered: grid points of the zone within w/2 of a strand. The
            // band of `perimeter_inset` along the part's outline is left by design (the
            // external perimeter is pulled in by it, its bead spreads there).
            let target = intersection(&plan.zone, &offset(&area, -settings.perimeter_inset));
            let strands: Vec<&Polyline> = plan.strands.iter().map(|s| &s.points).collect();
            let b = geo::BoundingRect::bounding_rect(&target).unwrap();
            let (mut inside, mut covered) = (0usize, 0usize);
            let g = 0.05;
            let mut y = b.min().y + g / 2.0;
            while y < b.max().y {
                let mut x = b.min().x + g / 2.0;
                while x < b.max().x {
                    if target.contains(&geo::Point::new(x, y)) {
                        inside += 1;
                        if dist_to([x, y], &strands) <= W / 2.0 + 1e-9 {
                            covered += 1;
                        }
                    }
                    x += g;
                }
                y += g;
            }
            let share = covered as f64 / inside.max(1) as f64;
            assert!(share >= 0.98, "{name}: zone {:.1} % covered", 100.0 * share);
        }
    }

    /// Loops and perimeter of the test bead width `W`, tolerance half of it.
    fn bead_widths() -> Widths {
        Widths {
            loop_width: W,
            perimeter_width: W,
            tolerance: W / 2.0,
        }
    }

    /// The length of `plan`'s loop strands and the straight hops from each to the next.
    fn loops_length_and_hops(plan: &Plan) -> (f64, f64) {
        let loops: Vec<&Strand> = plan
            .strands
            .iter()
            .filter(|s| s.kind == StrandKind::Loop)
            .collect();
        let length: f64 = loops.iter().map(|s| s.length()).sum();
        let hops: f64 = loops
            .windows(2)
            .map(|p| dist2(p[0].points[p[0].points.len() - 1], p[1].points[0]).sqrt())
            .sum();
        (length, hops)
    }

    /// The deposition check's rule on every strand of `plan`: each point is held where
    /// material lies within a quarter width of it, below or laid earlier in the plan.
    fn assert_each_strand_held(plan: &Plan, below: &MultiPolygon<f64>) {
        let edge = rings(below);
        let edge: Vec<&Polyline> = edge.iter().collect();
        for (i, s) in plan.strands.iter().enumerate() {
            let before: Vec<&Polyline> = plan.strands[..i].iter().map(|s| &s.points).collect();
            for p in samples(&s.points, 0.1) {
                let on_below = below.contains(&geo::Point::new(p[0], p[1]))
                    || dist_to(p, &edge) <= W / 4.0 + 1e-6;
                let on_earlier = dist_to(p, &before) <= W / 2.0 + W / 4.0 + 1e-6;
                assert!(
                    on_below || on_earlier,
                    "strand {i} ({:?} {}) hangs at {p:?} ({:.4} from earlier)",
                    s.kind,
                    s.loop_index,
                    dist_to(p, &before)
                );
            }
        }
    }

    #[test]
    fn a_square_ledge_s_corner_bits_are_laid_from_its_ring_not_toured_after_it() {
        // A 2 mm ledge round a 10 mm square post: the loops round the corners as arcs, so
        // the last ones are four corner bits. Toured after the last ring they cost a travel
        // along each side (12 % of the loops' length); laid from the ring as it passes,
        // a step out and one back.
        let below = mp(vec![rect(2.0, 2.0, 12.0, 12.0)]);
        let area = mp(vec![rect(0.0, 0.0, 14.0, 14.0)]);
        let band = difference(&area, &below);
        let widths = bead_widths();
        let plan = plan_over(
            band.0[0].clone(),
            &below,
            &area,
            widths,
            &PoaSettings::default(),
        );
        assert!(plan.loops >= 4, "{}", plan.loops);
        assert_each_strand_held(&plan, &below);
        let (length, hops) = loops_length_and_hops(&plan);
        assert!(
            hops < 0.06 * length,
            "{hops:.1} mm between loop strands for {length:.1} mm of loops"
        );
        // The corners are still filled: every point of the ledge within reach of a strand.
        let strands: Vec<&Polyline> = plan.strands.iter().map(|s| &s.points).collect();
        for (x, y) in [
            (0.3, 0.3),
            (13.7, 0.3),
            (0.3, 13.7),
            (13.7, 13.7),
            (1.0, 1.0),
        ] {
            let d = dist_to([x, y], &strands);
            assert!(d <= 0.6 * W, "corner ({x}, {y}) {d:.3} mm from a strand");
        }
    }

    #[test]
    fn a_gap_inside_a_wall_is_filled_from_both_beads_each_strand_leaning_on_what_came_before() {
        // A one-perimeter wall below: an outer bead (0 to 0.45) and the inner part (from
        // 1.55 in), a 1.1 mm gap between them; the layer prints all of it. The contour along
        // the outer bead lies 0.095 mm off it: it rests on the bead as loop 1 would, and the
        // loops beside it lean on it, so it is laid before them.
        let outer = geo::Polygon::new(
            rect(0.0, 0.0, 20.0, 20.0).exterior().clone(),
            vec![rect(0.45, 0.45, 19.55, 19.55).exterior().clone()],
        );
        let below = union(&mp(vec![outer]), &mp(vec![rect(1.55, 1.55, 18.45, 18.45)]));
        let area = mp(vec![rect(0.0, 0.0, 20.0, 20.0)]);
        let band = difference(&area, &below);
        let settings = PoaSettings::default();
        let widths = bead_widths();
        let plan = plan_over(band.0[0].clone(), &below, &area, widths, &settings);
        assert!(plan.loops >= 1);
        assert_each_strand_held(&plan, &below);
        // And the gap is filled (where the fronts from the two beads meet, a hairline).
        let strands: Vec<&Polyline> = plan.strands.iter().map(|s| &s.points).collect();
        for k in 0..40 {
            let y = 2.0 + 0.4 * k as f64;
            for x in [0.6, 0.8, 1.0, 1.2, 1.4] {
                let d = dist_to([x, y], &strands);
                assert!(
                    d <= 0.6 * W,
                    "({x}, {y}) left empty: {d:.3} mm from a strand"
                );
            }
        }
    }

    #[test]
    fn pieces_in_a_row_are_ordered_with_the_least_travel() {
        // Greedy from X 1.2 takes A (back to X 0), then C, then crosses back to B: 5.2 mm.
        // B first, then A and C going back costs 3.8 mm.
        let a = vec![[0.0, 0.0], [1.0, 0.0]];
        let b = vec![[2.0, 0.0], [3.0, 0.0]];
        let c = vec![[-2.0, 0.0], [-1.0, 0.0]];
        let travel = |seq: &[Polyline], from: [f64; 2]| {
            let mut at = from;
            let mut t = 0.0;
            for p in seq {
                t += dist2(at, p[0]).sqrt();
                at = p[p.len() - 1];
            }
            t
        };
        let pieces = vec![a, b, c];
        let from = [1.2, 0.0];
        let g = greedy(pieces.clone(), &mut from.clone());
        assert!((travel(&g, from) - 5.2).abs() < 1e-9);
        let mut at = from;
        let o = order(pieces, &mut at);
        assert!((travel(&o, from) - 3.8).abs() < 1e-9, "{o:?}");
        assert_eq!(at, o[2][1]);
        assert_eq!(o.len(), 3);
    }

    #[test]
    fn a_ladder_lays_one_arm_s_rungs_before_the_next_arm_s() {
        // Two arms 1 mm wide and 10 mm long out of a square's two sides (a wheel's spokes):
        // each front has a rung in each arm. Laid front by front, the nozzle crossed from
        // arm to arm at every rung; each arm's rungs now follow one another, outward.
        let below = mp(vec![rect(0.0, 0.0, 4.0, 4.0)]);
        let zone = mp(vec![rect(4.0, 1.5, 14.0, 2.5), rect(1.5, 4.0, 2.5, 14.0)]);
        let step = (1.0 - 0.4) * W;
        let front = offset(&below, step - W / 2.0);
        let plan = ladder(&zone, &front, W, step, [0.0, 0.0]).expect("rungs");
        let arm =
            |s: &Strand| s.points.iter().map(|q| q[0]).sum::<f64>() > 4.0 * s.points.len() as f64;
        let arms: Vec<bool> = plan.strands.iter().map(arm).collect();
        let switches = arms.windows(2).filter(|a| a[0] != a[1]).count();
        assert!(plan.strands.len() > 20 && switches == 1, "{arms:?}");
        // Outward along each arm: each rung farther from the square than the one before.
        for which in [true, false] {
            let reach: Vec<f64> = plan
                .strands
                .iter()
                .filter(|s| arm(s) == which)
                .map(|s| {
                    let q = s.points[0];
                    if which {
                        q[0]
                    } else {
                        q[1]
                    }
                })
                .collect();
            assert!(reach.windows(2).all(|r| r[1] > r[0]), "{reach:?}");
            assert!(reach[reach.len() - 1] > 13.0, "{reach:?}");
        }
    }

    #[test]
    fn square_cantilever() {
        check(
            "square",
            mp(vec![rect(0.0, 0.0, 10.0, 10.0)]),
            mp(vec![rect(0.0, 0.0, 16.0, 10.0)]),
            default_overlap(),
        );
    }

    #[test]
    fn the_perimeter_stays_out_under_the_layer_above_past_the_outline() {
        // A 6 mm cantilever: the layer above goes on past its tip (X 16) but not past its
        // sides. The perimeter is pulled in by the inset along the sides and stays where the
        // slicer put it (half a width inside) along the tip.
        let below = mp(vec![rect(0.0, 0.0, 10.0, 10.0)]);
        let area = mp(vec![rect(0.0, 0.0, 16.0, 10.0)]);
        let settings = PoaSettings::default();
        let widths = bead_widths();
        let poly = difference(&area, &below).0[0].clone();
        let plan_with = |others: &Others| {
            plan(
                &region(poly.clone(), &below),
                &below,
                &area,
                others,
                widths,
                &settings,
                [0.0, 0.0],
            )
        };
        // The perimeter's points near the line x = 16 (tip) and y = 10 (side), as distances
        // inside the outline.
        let inside_at = |p: &Plan, tip: bool| -> Vec<f64> {
            p.strands
                .iter()
                .filter(|s| s.kind == StrandKind::Perimeter)
                .flat_map(|s| samples(&s.points, 0.1))
                .filter(|q| {
                    if tip {
                        q[1] > 3.0 && q[1] < 7.0
                    } else {
                        q[0] > 12.0 && q[0] < 14.0
                    }
                })
                .map(|q| {
                    if tip {
                        16.0 - q[0]
                    } else {
                        (10.0 - q[1]).min(q[1])
                    }
                })
                .filter(|d| *d < 2.0 * W)
                .collect()
        };
        let plain = plan_with(&Others::default());
        let above = Others {
            // The layer above's bridge on past the tip, found as a region from the
            // tolerance past it.
            overhung: mp(vec![rect(16.0 + W / 2.0, 0.0, 20.0, 10.0)]),
            ..Others::default()
        };
        let under = plan_with(&above);
        let inset = settings.perimeter_inset;
        for (p, tip_at) in [(&plain, W / 2.0 + inset), (&under, W / 2.0)] {
            let tip = inside_at(p, true);
            assert!(!tip.is_empty());
            assert!(tip.iter().all(|d| (d - tip_at).abs() < 0.01), "tip {tip:?}");
            let side = inside_at(p, false);
            assert!(!side.is_empty());
            assert!(
                side.iter().all(|d| (d - (W / 2.0 + inset)).abs() < 0.01),
                "side {side:?}"
            );
        }
    }

    #[test]
    fn square_at_other_overlaps() {
        for overlap in [0.2, 0.6] {
            check(
                "overlap",
                mp(vec![rect(0.0, 0.0, 10.0, 10.0)]),
                mp(vec![rect(0.0, 0.0, 14.0, 10.0)]),
                overlap,
            );
        }
    }

    #[test]
    fn l_shape() {
        let area = union(
            &mp(vec![rect(0.0, 0.0, 15.0, 8.0)]),
            &mp(vec![rect(0.0, 0.0, 8.0, 15.0)]),
        );
        check(
            "L",
            mp(vec![rect(0.0, 0.0, 5.0, 5.0)]),
            area,
            default_overlap(),
        );
    }

    #[test]
    fn ring_around_a_column() {
        // A mushroom cap: the region is a ring with the column as its hole.
        check(
            "ring",
            mp(vec![rect(0.0, 0.0, 6.0, 6.0)]),
            mp(vec![rect(-4.0, -4.0, 10.0, 10.0)]),
            default_overlap(),
        );
    }

    #[test]
    fn seams_of_closed_loops_do_not_stack() {
        // Around a column every loop is a closed ring: each seam moves along from the one
        // before, by more than a width (no lumpy line of seams), by less than two (the hop
        // goes without retraction), and the rings still close where they start.
        let below = mp(vec![rect(0.0, 0.0, 6.0, 6.0)]);
        let area = mp(vec![rect(-4.0, -4.0, 10.0, 10.0)]);
        let poly = difference(&area, &below).0.remove(0);
        let widths = bead_widths();
        let settings = PoaSettings::default();
        let plan = plan_over(poly, &below, &area, widths, &settings);
        let rings: Vec<&Polyline> = plan
            .strands
            .iter()
            .filter(|s| s.kind == StrandKind::Loop && is_closed(&s.points))
            .map(|s| &s.points)
            .collect();
        assert!(rings.len() >= 5, "{} closed loops", rings.len());
        for pair in rings.windows(2) {
            let (a, b) = (pair[0][0], pair[1][0]);
            let hop = dist2(a, b).sqrt();
            assert!(hop > W && hop <= 2.0 * W, "seams {hop:.3} mm apart");
            // The same ring as planned: its length is the planned ring's.
            assert!(polyline_length(pair[1]) > 10.0 * seam_stagger(W, 0.6 * W));
        }
    }

    #[test]
    fn two_islands() {
        let below = mp(vec![rect(0.0, 0.0, 5.0, 5.0), rect(20.0, 0.0, 25.0, 5.0)]);
        let area = mp(vec![rect(0.0, 0.0, 10.0, 5.0), rect(20.0, 0.0, 28.0, 5.0)]);
        check("islands", below, area, default_overlap());
    }

    #[test]
    fn a_shelf_with_a_hole_is_printed_lobe_by_lobe() {
        // A 15 mm shelf off a wall with an 8 mm hole: the fronts split around the hole.
        let hole: Vec<geo::Coord<f64>> = (0..=48)
            .map(|i| {
                let a = i as f64 / 48.0 * std::f64::consts::TAU;
                geo::coord! {x: 18.0 + 4.0 * a.cos(), y: 15.0 + 4.0 * a.sin()}
            })
            .collect();
        let shelf = difference(
            &mp(vec![rect(0.0, 0.0, 25.0, 30.0)]),
            &MultiPolygon::new(vec![geo::Polygon::new(geo::LineString::new(hole), vec![])]),
        );
        let below = mp(vec![rect(0.0, 0.0, 10.0, 30.0)]);
        check("shelf", below.clone(), shelf.clone(), default_overlap());
        let widths = bead_widths();
        let zone = difference(&shelf, &below);
        let plan = plan_over(
            zone.0[0].clone(),
            &below,
            &shelf,
            widths,
            &PoaSettings::default(),
        );
        let (length, travel) = loops_length_and_hops(&plan);
        assert!(
            travel <= 0.10 * length,
            "travel {travel:.1} mm for {length:.1} mm of loops"
        );
    }

    /// A U along two arms and round a bow at (10, 0): arms `r` either side of y = 0 from
    /// x = 0 to 10, the bow a half circle of radius `r`; only the bow where `bow_only`.
    fn bow(r: f64, bow_only: bool) -> Polyline {
        let mut p = Vec::new();
        if !bow_only {
            p.push([0.0, -r]);
        }
        for k in 0..=32 {
            let a = -std::f64::consts::FRAC_PI_2 + std::f64::consts::PI * k as f64 / 32.0;
            p.push([10.0 + r * a.cos(), r * a.sin()]);
        }
        if !bow_only {
            p.push([0.0, r]);
        }
        p
    }

    #[test]
    fn a_perimeter_is_laid_in_stretches_as_the_strands_it_leans_on_are_laid() {
        // A hull's bow: loop 1 along both sides and round the bow, loop 2 round the bow only,
        // the perimeter outside both along the sides and round the bow. Laid whole after
        // loop 2, the perimeter starts at one side's far end: two hops the length of a side.
        // The same with a contour round the bow in place of loop 2 (a region's plan).
        for bow_only in [(StrandKind::Loop, 2), (StrandKind::Contour, 0)] {
            bow_plan(bow_only);
        }
    }

    /// [`a_perimeter_is_laid_in_stretches_as_the_strands_it_leans_on_are_laid`] with a strand
    /// of this kind and loop number round the bow only.
    fn bow_plan((kind, index): (StrandKind, usize)) {
        let strand = |kind, loop_index, points| Strand {
            kind,
            loop_index,
            points,
            width: W,
        };
        let start = [0.0, -2.0];
        let mut plan = vec![
            strand(StrandKind::Loop, 1, bow(2.0, false)),
            strand(kind, index, bow(2.35, true)),
            strand(StrandKind::Perimeter, 0, bow(2.7, false)),
        ];
        arrange(&mut plan, start);
        let before = travel_of(&plan, start);
        let perimeter = polyline_length(&bow(2.7, false));
        let mut cut = plan.clone();
        split_perimeters(&mut cut, start);
        let after = travel_of(&cut, start);
        assert!(
            before > 15.0 && after < 0.4 * before,
            "{before:.1} -> {after:.1} mm"
        );
        // Nothing of the perimeter lost or laid twice.
        let laid: f64 = cut
            .iter()
            .filter(|s| s.kind == StrandKind::Perimeter)
            .map(|s| s.length())
            .sum();
        assert!((laid - perimeter).abs() < 1e-6, "{laid} vs {perimeter}");
        // Every point of the perimeter within two widths of a loop is laid after that loop,
        // and loop 2 after loop 1 wherever it lies beside it.
        let near = |p: [f64; 2], s: &Strand| {
            s.points.windows(2).any(|g| {
                let (_, m) = crate::geometry::nearest_on_segment(p, g[0], g[1]);
                dist2(p, m) <= (2.0 * W) * (2.0 * W)
            })
        };
        for (i, s) in cut.iter().enumerate() {
            for (j, t) in cut.iter().enumerate() {
                let leans = match (s.kind, t.kind) {
                    (StrandKind::Loop, StrandKind::Loop) => s.loop_index > t.loop_index,
                    (a, b) => (b as usize) < (a as usize),
                };
                if leans && s.points.iter().any(|&p| near(p, t)) {
                    assert!(
                        j < i,
                        "strand {i} ({:?}) laid before strand {j} it leans on",
                        s.kind
                    );
                }
            }
        }
        // The stretches laid one after the other are one strand: at most three pieces.
        let pieces = cut
            .iter()
            .filter(|s| s.kind == StrandKind::Perimeter)
            .count();
        assert!((2..=3).contains(&pieces), "{pieces} pieces");
    }

    #[test]
    fn a_ring_laid_after_the_loops_starts_on_a_bead_they_laid() {
        // One loop along y = 0, then a perimeter ring whose corner nearest the loop's end
        // stands 0.8 mm off it, over nothing; its side along the loop lies on the loop's bead.
        let strand = |kind, points: Vec<[f64; 2]>| Strand {
            kind,
            loop_index: if kind == StrandKind::Loop { 1 } else { 0 },
            points,
            width: W,
        };
        let base = vec![strand(StrandKind::Loop, vec![[0.0, 0.0], [10.0, 0.0]])];
        let ring = vec![
            [0.0, 0.25],
            [8.0, 0.25],
            [10.5, 0.8],
            [10.5, 5.0],
            [0.0, 5.0],
            [0.0, 0.25],
        ];
        let pool = vec![strand(StrandKind::Perimeter, ring)];
        let out = pull_forward(&base, &pool, (2.0 * W, W), 0, &MultiPolygon::new(vec![]))
            .expect("a plan this small is weighed");
        assert_eq!(out.len(), 2);
        let seam = out[1].points[0];
        assert!(
            seam[1] <= 0.25 + 1e-9,
            "the ring starts at {seam:?}, off the loop's bead"
        );
        assert!(is_closed(&out[1].points));
    }

    #[test]
    fn pieces_meeting_end_to_end_are_chained_into_one() {
        let a = vec![[0.0, 0.0], [5.0, 0.0]];
        // Meets a's start with its start, and c's end with its end.
        let b = vec![[-0.1, 0.0], [-5.0, 0.0], [-5.0, 5.0]];
        let c = vec![[5.0, 10.0], [-5.0, 5.1]];
        let far = vec![[20.0, 0.0], [25.0, 0.0]];
        let ring = vec![[5.05, 0.0], [8.0, 0.0], [8.0, 3.0], [5.05, 0.0]];
        let out = chained(&[a, b, far.clone(), c, ring.clone()], 0.2);
        assert_eq!(out.len(), 3, "{out:?}");
        let long = out
            .iter()
            .find(|p| p.len() == 7)
            .expect("a, b and c in one");
        let ends = [long[0], long[6]];
        assert!(
            ends.contains(&[5.0, 0.0]) && ends.contains(&[5.0, 10.0]),
            "{long:?}"
        );
        for w in long.windows(2) {
            assert!(dist2(w[0], w[1]).sqrt() < 11.2, "{long:?}");
        }
        assert!(out.contains(&far) && out.contains(&ring));
    }

    #[test]
    fn a_shelf_pierced_by_holes_finishes_each_hole_as_its_loops_pass_it() {
        // A 30 mm plate on a 12 mm post, pierced by sixteen 3 mm holes round it: the fronts
        // pass hole after hole. Toured after the loops, every hole's contour and perimeter
        // cost a travel there (11.7 % of the plan's length on a sliced plate like it); laid
        // as the loops leave each hole behind, a short hop out and back.
        let ring = |cx: f64, cy: f64, r: f64, n: usize| -> Polygon<f64> {
            let pts: Vec<geo::Coord<f64>> = (0..=n)
                .map(|i| {
                    let a = i as f64 / n as f64 * std::f64::consts::TAU;
                    geo::coord! {x: cx + r * a.cos(), y: cy + r * a.sin()}
                })
                .collect();
            Polygon::new(geo::LineString::new(pts), vec![])
        };
        let holes: Vec<Polygon<f64>> = (0..5)
            .flat_map(|i| (0..5).map(move |j| (i, j)))
            .filter(|&(i, j)| i == 0 || i == 4 || j == 0 || j == 4)
            .map(|(i, j)| ring(5.0 + 5.0 * i as f64, 5.0 + 5.0 * j as f64, 1.5, 24))
            .collect();
        // Rounded corners: a square corner's contour stands past the loops' arcs there.
        let plate = difference(
            &offset(&mp(vec![rect(3.0, 3.0, 27.0, 27.0)]), 3.0),
            &MultiPolygon::new(holes),
        );
        let below = MultiPolygon::new(vec![ring(15.0, 15.0, 6.0, 48)]);
        let widths = bead_widths();
        let zone = difference(&plate, &below);
        let plan = plan_over(
            zone.0[0].clone(),
            &below,
            &plate,
            widths,
            &PoaSettings::default(),
        );
        let length: f64 = plan.strands.iter().map(|s| s.length()).sum();
        let travel = hop_travel(&plan.strands);
        assert_each_strand_held(&plan, &below);
        assert!(
            travel <= 0.10 * length,
            "travel {travel:.1} mm for {length:.1} mm of strands"
        );
        // Each ring of the contour or perimeter starts on a bead laid before it.
        for (k, f) in plan.strands.iter().enumerate() {
            if f.kind == StrandKind::Loop || !is_closed(&f.points) {
                continue;
            }
            let seam = f.points[0];
            let held = plan.strands[..k].iter().any(|s| {
                let r = s.width / 2.0 + HELD_CUT * f.width + 1e-6;
                s.points.windows(2).any(|q| {
                    dist2(
                        crate::geometry::nearest_on_segment(seam, q[0], q[1]).1,
                        seam,
                    ) <= r * r
                })
            });
            assert!(held, "a {:?} ring starts at {seam:?}, on nothing", f.kind);
        }
        // No loop laid after a piece of the contour or perimeter touches it.
        let touch = (widths.loop_width + widths.perimeter_width) / 2.0 + 0.05;
        for (k, f) in plan.strands.iter().enumerate() {
            if f.kind == StrandKind::Loop {
                continue;
            }
            for l in plan.strands[k + 1..]
                .iter()
                .filter(|s| s.kind == StrandKind::Loop)
            {
                assert!(
                    !crate::geometry::polylines_within(&l.points, &f.points, touch),
                    "loop {} laid against a {:?} piece laid before it",
                    l.loop_index,
                    f.kind
                );
            }
        }
    }

    /// The centrelines of a plan's perimeter strands.
    fn perimeter_lines(plan: &Plan) -> Vec<&Polyline> {
        plan.strands
            .iter()
            .filter(|s| s.kind == StrandKind::Perimeter)
            .map(|s| &s.points)
            .collect()
    }

    #[test]
    fn a_gear_s_teeth_narrower_than_two_perimeters_keep_their_perimeter() {
        // A 26 mm gear over an 8 mm stem, 24 teeth 1.6 mm wide standing 1.5 mm out, with a
        // 0.8 mm nozzle's 0.9 mm beads: rounded by half a width, the perimeter lost every
        // tooth (the layer above then bridged them all). Each tooth keeps its perimeter,
        // out to the tip less the bead's half width and the inset.
        let w = 0.9;
        let widths = Widths {
            loop_width: w,
            perimeter_width: w,
            tolerance: w / 2.0,
        };
        let mut gear = mp(vec![disc(13.0, 96)]);
        let tip = 14.5;
        for i in 0..24 {
            let t = std::f64::consts::TAU * i as f64 / 24.0;
            let (c, s) = (t.cos(), t.sin());
            let at = |r: f64, q: f64| (10.0 + r * c - q * s, 10.0 + r * s + q * c);
            let tooth: Polygon<f64> = Polygon::new(
                vec![at(12.0, -0.8), at(tip, -0.8), at(tip, 0.8), at(12.0, 0.8)].into(),
                vec![],
            );
            gear = union(&gear, &mp(vec![tooth]));
        }
        let below = mp(vec![disc(4.0, 48)]);
        let band = difference(&gear, &below);
        let settings = PoaSettings::default();
        let plan = plan_over(band.0[0].clone(), &below, &gear, widths, &settings);
        let perimeter = perimeter_lines(&plan);
        assert!(!perimeter.is_empty());
        let reach = tip - w / 2.0 - settings.perimeter_inset;
        for i in 0..24 {
            let t = std::f64::consts::TAU * i as f64 / 24.0;
            let p = [10.0 + reach * t.cos(), 10.0 + reach * t.sin()];
            let d = dist_to(p, &perimeter);
            assert!(
                d < 0.3 * w,
                "tooth {i}: its tip {d:.2} mm from the perimeter"
            );
        }
        // A square corner is still rounded: nothing of this is a feature.
        let square = mp(vec![rect(0.0, 0.0, 20.0, 20.0)]);
        let post = mp(vec![rect(6.0, 6.0, 14.0, 14.0)]);
        let ring = difference(&square, &post);
        let plan = plan_over(ring.0[0].clone(), &post, &square, widths, &settings);
        let perimeter = perimeter_lines(&plan);
        let corner = w / 2.0 + settings.perimeter_inset;
        let d = dist_to([corner, corner], &perimeter);
        assert!(d > 0.1 * w, "a square's corner kept sharp: {d:.3} mm");
    }

    /// A regular polygon of `n` corners round (10, 10).
    fn disc(r: f64, n: usize) -> Polygon<f64> {
        let pts: Vec<(f64, f64)> = (0..n)
            .map(|i| {
                let t = std::f64::consts::TAU * i as f64 / n as f64;
                (10.0 + r * t.cos(), 10.0 + r * t.sin())
            })
            .collect();
        Polygon::new(pts.into(), vec![])
    }

    /// A gradual overhang `o` mm past the wall below, from a fraction of a width to almost
    /// four, as a straight strip (an arch's layer) and as a ring (a sphere's): every strand
    /// of the plan rests on what is printed before it (the layer below or an earlier strand)
    /// (material within a quarter of its width, as the deposition check asks; 0.3 for the
    /// perimeter, see [`NEAR_LOOP_AT`]), and the perimeter comes last.
    #[test]
    fn a_gradual_overhang_of_any_width_rests_on_what_is_printed_before() {
        let widths = bead_widths();
        type Case = (
            MultiPolygon<f64>,
            MultiPolygon<f64>,
            Box<dyn Fn([f64; 2]) -> f64>,
        );
        for tenths in 3..=40 {
            let o = W * f64::from(tenths) / 10.0;
            let cases: Vec<(&str, Case)> = vec![
                (
                    "strip",
                    (
                        mp(vec![rect(0.0, 0.0, 10.0, 10.0)]),
                        mp(vec![rect(0.0, 0.0, 10.0 + o, 10.0)]),
                        // Away from the strip's ends, where strands turn along its edge.
                        Box::new(|p: [f64; 2]| {
                            if p[1] < 1.0 || p[1] > 9.0 {
                                0.0
                            } else {
                                (p[0] - 10.0).max(0.0)
                            }
                        }),
                    ),
                ),
                (
                    "ring",
                    (
                        mp(vec![disc(5.0, 256)]),
                        mp(vec![disc(5.0 + o, 256)]),
                        Box::new(|p: [f64; 2]| ((p[0] - 10.0).hypot(p[1] - 10.0) - 5.0).max(0.0)),
                    ),
                ),
            ];
            for (name, (below, area, to_below)) in cases {
                let zone = difference(&area, &below);
                let plan = plan_over(
                    zone.0[0].clone(),
                    &below,
                    &area,
                    widths,
                    &PoaSettings::default(),
                );
                if plan.strands.is_empty() {
                    // Only where the slicer's perimeter rests on the wall below as it is.
                    assert!(o - W / 2.0 <= 0.3 * W, "{name} o {o:.3}: nothing planned");
                    continue;
                }
                let last = plan.strands.last().unwrap();
                assert_eq!(last.kind, StrandKind::Perimeter, "{name} o {o:.3}");
                for (i, s) in plan.strands.iter().enumerate() {
                    let before = &plan.strands[..i];
                    for p in samples(&s.points, 0.05) {
                        let to_earlier = before
                            .iter()
                            .map(|b| dist_to(p, &[&b.points]) - b.width / 2.0)
                            .fold(f64::INFINITY, f64::min);
                        let gap = to_below(p).min(to_earlier);
                        // Loops as the check asks; the perimeter see [`NEAR_LOOP_AT`].
                        let reach = if s.kind == StrandKind::Perimeter {
                            0.3
                        } else {
                            0.25
                        };
                        assert!(
                            gap <= reach * s.width + 1e-6,
                            "{name} o {o:.3}: {:?} {} at {p:?} is {gap:.3} mm from material",
                            s.kind,
                            s.loop_index,
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn regions_either_side_of_a_narrow_slot_each_plan_their_own_side() {
        // Two blocks 2 mm apart; the layer closes the slot to 0.3 mm: two slivers 0.85 mm
        // wide, each within the other's window. Each plan lays strands on its own side only
        // (each laid the other side's perimeter too: twice over, once in air).
        let below = mp(vec![
            rect(0.0, 0.0, 10.0, 20.0),
            rect(12.0, 0.0, 22.0, 20.0),
        ]);
        let area = mp(vec![
            rect(0.0, 0.0, 10.85, 20.0),
            rect(11.15, 0.0, 22.0, 20.0),
        ]);
        let settings = PoaSettings::default();
        let slivers = difference(&area, &below);
        assert_eq!(slivers.0.len(), 2);
        for poly in &slivers.0 {
            let left = geo::Centroid::centroid(poly).is_some_and(|c| c.x() < 11.0);
            let plan = plan_over(poly.clone(), &below, &area, bead_widths(), &settings);
            assert!(!plan.strands.is_empty());
            for s in &plan.strands {
                for p in &s.points {
                    assert_eq!(p[0] < 11.0, left, "{:?} strand at {p:?}", s.kind);
                }
            }
        }
    }

    /// V notches `depth` deep with a mouth `mouth` wide, every `pitch` mm along the line
    /// x = `x` from y = 1 to 19, opening towards -x (`dir` -1) or +x (`dir` 1).
    fn notches(x: f64, dir: f64, mouth: f64, depth: f64, pitch: f64) -> MultiPolygon<f64> {
        let mut v = Vec::new();
        let mut y = 1.0;
        while y + mouth < 19.0 {
            v.push(Polygon::new(
                vec![
                    (x - dir * 0.01, y),
                    (x + dir * depth, y + mouth / 2.0),
                    (x - dir * 0.01, y + mouth),
                ]
                .into(),
                vec![],
            ));
            y += pitch;
        }
        MultiPolygon::new(v)
    }

    /// The plan of the largest piece of `area` over air past `below`.
    fn plan_biggest(below: &MultiPolygon<f64>, area: &MultiPolygon<f64>) -> Plan {
        let zone = difference(area, below);
        let biggest = zone
            .0
            .iter()
            .max_by(|a, b| a.unsigned_area().total_cmp(&b.unsigned_area()))
            .unwrap()
            .clone();
        plan_over(biggest, below, area, bead_widths(), &PoaSettings::default())
    }

    /// A hollow wall standing on a shelf's edge (two shelves with a hole, sliced hollow): the
    /// wall's side over the shelf rests on it, the rest of the ring hangs over the wall's
    /// hollow inside. Loops are laid from the shelf's edge inward, the perimeter facing the
    /// hollow last; the moved perimeter along the shelf's edge (0.3 mm past it, in air, first)
    /// is gone. The shelf's top layer ends in the notches its infill's turns leave (a ring
    /// clipped at each was pieces too short to lay, and its loop was lost): the same.
    #[test]
    fn a_wall_standing_on_a_shelf_s_edge_is_held_from_the_shelf_inward() {
        for notched in [false, true] {
            let mut below = mp(vec![
                rect(1.22, -5.0, 15.0, 25.0),
                rect(-1.0, -2.0, 1.25, 1.0),
                rect(-1.0, 19.0, 1.25, 22.0),
            ]);
            if notched {
                below = difference(&below, &notches(1.22, 1.0, 0.4, 0.25, 1.13));
            }
            let area = mp(vec![rect(0.0, -2.0, 1.25, 22.0)]);
            let plan = plan_biggest(&below, &area);
            assert!(plan.loops >= 2, "notched {notched}: {} loops", plan.loops);
            // (A bead crosses a notch's mouth, narrower than a width, as it crosses a gap
            // between infill lines: held across it.)
            assert_each_strand_held(&plan, &closing(&below, W / 2.0));
        }
    }

    /// A roof over a hollow part (PrusaSlicer, 0.25 mm layers): its bridge lines run at 45
    /// degrees to the wall, 0.3 mm clear of its inner perimeter, and turn in pairs, leaving V
    /// notches 0.4 mm deep along the wall below's edge. Loops 1 and 2 lay in the notches and
    /// within a contour's room of the roof's edge: clipped to nothing; the first loop laid
    /// was 0.58 mm past the wall, in air (95.8 mm on the layer). Gaps that narrow are filled
    /// from the wall: the loops start at it, and the notches are printed.
    #[test]
    fn notches_between_a_wall_and_a_roof_are_filled_by_the_first_loops() {
        let below = mp(vec![rect(-1.5, -2.0, 0.0, 22.0)]);
        let cut = notches(-0.06, 1.0, 0.44, 0.46, 1.285);
        let area = difference(
            &mp(vec![
                rect(-1.5, -2.0, -0.36, 22.0),
                rect(-0.06, -2.0, 10.0, 22.0),
            ]),
            &cut,
        );
        let plan = plan_biggest(&below, &area);
        assert!(plan.loops >= 10, "{} loops", plan.loops);
        assert_each_strand_held(&plan, &closing(&below, W / 2.0));
        // The notches are printed: every point of them past the wall within half a width of
        // a strand.
        let strands: Vec<&Polyline> = plan.strands.iter().map(|s| &s.points).collect();
        let holes = intersection(&cut, &mp(vec![rect(0.0, 2.0, 10.0, 18.0)]));
        assert!(!holes.0.is_empty());
        for p in &holes.0 {
            for c in &p.exterior().0 {
                assert!(
                    dist_to([c.x, c.y], &strands) <= W / 2.0 + 0.02,
                    "notch point {c:?} not printed"
                );
            }
        }
    }

    #[test]
    fn thin_sliver() {
        check(
            "sliver",
            mp(vec![rect(0.0, 0.0, 10.0, 10.0)]),
            mp(vec![rect(0.0, 0.0, 11.2, 10.0)]),
            default_overlap(),
        );
    }
}
