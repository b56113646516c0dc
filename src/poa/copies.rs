//! Plans shared between copies of a part on one plate.
//!
//! Input: the regions of one layer chosen for a rewrite, each with its [`Others`], the
//! layer's printed area and the area below it. Output: one [`Plan`] per region, in their
//! order, each as [`plan`] makes it, or a translation of the plan of an earlier region whose
//! surroundings are the same shape moved (a plate of copies: `--duplicate`, arranged
//! instances). Invariants: a plan is shared only when everything the planner reads near the
//! region (the polygons of the area below and of the layer, whole when its windows hold them
//! whole, else what its windows cut out of them; the regions beside it) matches,
//! vertex for vertex, the earlier region's moved by one translation within [`MATCH_TOL`],
//! and the regions themselves have the same box, area, reach and holes there; otherwise
//! the region is planned on its own. Plans of representatives run on all cores.

use geo::{Area, BoundingRect, MultiPolygon, Polygon};

use super::{plan, Others, Plan, PoaSettings, Widths};
use crate::geometry::{near_refs, Region};

/// Largest difference (mm) between a vertex and its match moved by the translation: the
/// slicer writes micrometres, and the areas poa derives from two copies differ by float
/// noise well below that.
const MATCH_TOL: f64 = 2e-3;

/// A region's planning inputs as found near it: what decides whether two regions share a
/// plan.
struct Surroundings<'a> {
    region: &'a Region,
    others: &'a Others,
    // Borrowed, never copied: a layer's big polygon near many regions is held once.
    below: Vec<&'a Polygon<f64>>,
    area: Vec<&'a Polygon<f64>>,
    keep_out: Vec<&'a Polygon<f64>>,
    /// Corner of the region's box: where the translation is read.
    corner: [f64; 2],
    /// Where the planner's windows cut polygons (a region on the side of a big body): the
    /// windows' contents themselves, `below` and `area` then left empty.
    cut: Option<super::Windows>,
}

/// Representatives of one area a region is compared with.
const MAX_CANDIDATES: usize = 32;

/// Largest difference (mm) between two matching regions' reach ([`Region::max_distance`],
/// sampled at the region's vertices, which float noise moves: 15.0 to 15.5 mm between a
/// plate's mushroom caps).
const REACH_SLACK: f64 = 1.0;

/// Distance (mm) past a region's box within which [`plan`] reads the area below, for a
/// reach of `md`: the region grown by the tolerance and a width, then by the loops' reach
/// and a width.
fn below_window(md: f64, widths: &Widths) -> f64 {
    let (t, w) = (widths.tolerance, widths.loop_width);
    (t + w) + (md.min(1000.0) + t + 2.0 * w) + w
}

/// ... and the layer's area, two perimeter widths and 2 mm past the grown region.
fn area_window(widths: &Widths) -> f64 {
    (widths.tolerance + widths.loop_width) + 2.0 * widths.perimeter_width + 2.0
}

/// Whether every polygon of `set` (those whose boxes come within the outer window of `b`,
/// [`near_refs`]) lies within `inner` of `b`: then any window between the two selects those
/// polygons whole, as [`plan`] does with its own (which carries the noise of the region's
/// outline).
fn isolated(set: &[&Polygon<f64>], b: &geo::Rect<f64>, inner: f64) -> bool {
    set.iter().all(|p| {
        p.bounding_rect().is_some_and(|q| {
            q.min().x >= b.min().x - inner
                && q.max().x <= b.max().x + inner
                && q.min().y >= b.min().y - inner
                && q.max().y <= b.max().y + inner
        })
    })
}

/// A region's surroundings, when the planner reads them whole (see [`isolated`]).
fn surroundings<'a>(
    region: &'a Region,
    others: &'a Others,
    below: &'a MultiPolygon<f64>,
    area: &'a MultiPolygon<f64>,
    widths: &Widths,
) -> Option<Surroundings<'a>> {
    // The noise of the planner's own box (the region grown by a round offset).
    const EDGE: f64 = 0.05;
    let (below_all, area_all) = (below, area);
    let b = region.polygon.bounding_rect()?;
    let md = region.max_distance;
    let outer = below_window(md + REACH_SLACK, widths) + EDGE;
    let inner = below_window((md - REACH_SLACK).max(0.0), widths) - EDGE;
    let below = near_refs(below, &b, outer);
    let area_outer = area_window(widths) + EDGE;
    let area = near_refs(area, &b, area_outer);
    let whole = isolated(&below, &b, inner) && isolated(&area, &b, area_window(widths) - EDGE);
    // Otherwise what the planner cuts out of them (a box's edge cuts a copy's polygon where
    // it cuts the other's, moved, up to the noise of the region's outline, and the
    // comparison says whether it did).
    let cut = if whole {
        None
    } else {
        Some(super::windows(region, below_all, area_all, others, widths)?)
    };
    Some(Surroundings {
        region,
        others,
        below: if whole { below } else { Vec::new() },
        area: if whole { area } else { Vec::new() },
        keep_out: near_refs(&others.keep_out, &b, outer),
        corner: [b.min().x, b.min().y],
        cut,
    })
}

fn same_ring(a: &geo::LineString<f64>, b: &geo::LineString<f64>, t: [f64; 2]) -> bool {
    a.0.len() == b.0.len()
        && a.0.iter().zip(&b.0).all(|(p, q)| {
            (p.x + t[0] - q.x).abs() <= MATCH_TOL && (p.y + t[1] - q.y).abs() <= MATCH_TOL
        })
}

fn same_polygon(a: &Polygon<f64>, b: &Polygon<f64>, t: [f64; 2]) -> bool {
    a.interiors().len() == b.interiors().len()
        && same_ring(a.exterior(), b.exterior(), t)
        && a.interiors()
            .iter()
            .zip(b.interiors())
            .all(|(p, q)| same_ring(p, q, t))
}

/// Whether every polygon of `a` moved by `t` is the polygon of `b` at its place, vertex for
/// vertex.
fn same_shapes(a: &[&Polygon<f64>], b: &[&Polygon<f64>], t: [f64; 2]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(p, q)| same_polygon(p, q, t))
}

/// Whether the layer above's regions past the outline ([`Others::overhung`]) of two regions
/// are the same moved by `t`: as many, with the same boxes and areas, within
/// [`OVERHUNG_SLACK`] (found like the regions themselves, they carry the same noise; the
/// perimeter stays unmoved within a width or two of them, so a few hundredths change
/// nothing).
fn same_overhung(a: &MultiPolygon<f64>, b: &MultiPolygon<f64>, t: [f64; 2]) -> bool {
    let close = |x: f64, y: f64| (x - y).abs() <= OVERHUNG_SLACK;
    a.0.len() == b.0.len()
        && a.0
            .iter()
            .zip(&b.0)
            .all(|(p, q)| match (p.bounding_rect(), q.bounding_rect()) {
                (Some(pa), Some(qb)) => {
                    close(pa.min().x + t[0], qb.min().x)
                        && close(pa.min().y + t[1], qb.min().y)
                        && close(pa.max().x + t[0], qb.max().x)
                        && close(pa.max().y + t[1], qb.max().y)
                        && (p.unsigned_area() - q.unsigned_area()).abs()
                            <= OVERHUNG_SLACK * (1.0 + p.unsigned_area().sqrt())
                }
                (None, None) => true,
                _ => false,
            })
}

/// How far apart (mm) the edges of two copies' [`Others::overhung`] regions may lie.
const OVERHUNG_SLACK: f64 = 0.02;

/// The polygons of `m`, borrowed.
fn refs(m: &MultiPolygon<f64>) -> Vec<&Polygon<f64>> {
    m.0.iter().collect()
}

/// Whether two regions (derived with float noise) are the same region moved by `t`: box,
/// area, reach and holes.
fn same_region(a: &Region, b: &Region, t: [f64; 2]) -> bool {
    let (Some(ba), Some(bb)) = (a.polygon.bounding_rect(), b.polygon.bounding_rect()) else {
        return false;
    };
    let close = |x: f64, y: f64| (x - y).abs() <= MATCH_TOL;
    close(ba.min().x + t[0], bb.min().x)
        && close(ba.min().y + t[1], bb.min().y)
        && close(ba.max().x + t[0], bb.max().x)
        && close(ba.max().y + t[1], bb.max().y)
        && (a.area - b.area).abs() <= MATCH_TOL * (1.0 + a.area.max(b.area).sqrt())
        && (a.max_distance - b.max_distance).abs() <= REACH_SLACK
        // A narrow cantilever's plan is a ladder, or not, by its reach.
        && (a.max_distance > super::CANTILEVER_REACH) == (b.max_distance > super::CANTILEVER_REACH)
        && a.polygon.interiors().len() == b.polygon.interiors().len()
        && a.kind == b.kind
}

/// The translation taking `a`'s surroundings onto `b`'s, when they match.
fn translation(a: &Surroundings<'_>, b: &Surroundings<'_>) -> Option<[f64; 2]> {
    // The first vertex of the layer's polygons near by fixes the translation exactly (the
    // region's own box carries the noise of its derivation).
    let first = |s: &Surroundings<'_>| {
        let polygons = match &s.cut {
            Some(c) => c.area.0.first(),
            None => s.area.first().copied(),
        };
        polygons.and_then(|p| p.exterior().0.first().copied())
    };
    let t = match (first(a), first(b)) {
        (Some(p), Some(q)) => [q.x - p.x, q.y - p.y],
        (None, None) => [b.corner[0] - a.corner[0], b.corner[1] - a.corner[1]],
        _ => return None,
    };
    let plain = |o: &Others| o.absorb.0.is_empty();
    let windows = match (&a.cut, &b.cut) {
        (None, None) => same_shapes(&a.area, &b.area, t) && same_shapes(&a.below, &b.below, t),
        (Some(x), Some(y)) => {
            // The margin round the region (`hint`) is not compared, as the region's outline
            // is not: both carry the noise of the region's derivation, which `same_region`
            // bounds.
            same_shapes(&refs(&x.area), &refs(&y.area), t)
                && same_shapes(&refs(&x.below), &refs(&y.below), t)
        }
        _ => false,
    };
    (plain(a.others)
        && plain(b.others)
        && same_region(a.region, b.region, t)
        && windows
        && same_shapes(&a.keep_out, &b.keep_out, t)
        && same_overhung(&a.others.overhung, &b.others.overhung, t))
    .then_some(t)
}

fn translated(plan: &Plan, t: [f64; 2]) -> Plan {
    use geo::Translate;
    let mut out = plan.clone();
    out.zone.translate_mut(t[0], t[1]);
    for s in &mut out.strands {
        for p in &mut s.points {
            p[0] += t[0];
            p[1] += t[1];
        }
    }
    out
}

/// Each region's source: itself (a representative), or an earlier region it is a copy of,
/// moved by the translation given ([`plan_all`]'s matching).
pub type Sources = Vec<(usize, [f64; 2])>;

/// The copies among `regions` ([`Sources`]), as [`plan_all`] finds them.
pub fn copy_sources(
    regions: &[(&Region, &Others)],
    below: &MultiPolygon<f64>,
    area: &MultiPolygon<f64>,
    widths: Widths,
) -> Sources {
    use rayon::prelude::*;
    let around: Vec<Option<Surroundings<'_>>> = regions
        .par_iter()
        .map(|(r, o)| surroundings(r, o, below, area, &widths))
        .collect();
    sources_of(regions, &around)
}

fn sources_of(regions: &[(&Region, &Others)], around: &[Option<Surroundings<'_>>]) -> Sources {
    // Candidates are looked up by area (to 0.01 mm2; a pair split by the rounding is planned
    // twice), which keeps a layer of many different regions linear.
    let mut source: Sources = Vec::with_capacity(regions.len());
    let mut by_area: std::collections::HashMap<i64, Vec<usize>> = Default::default();
    for (i, s) in around.iter().enumerate() {
        let key = (regions[i].0.area * 100.0).round() as i64;
        let shared = s.as_ref().and_then(|s| {
            // A bounded number of candidates: a layer of many regions of one area that are
            // not copies stays linear.
            by_area
                .get(&key)?
                .iter()
                .take(MAX_CANDIDATES)
                .find_map(|&j| {
                    let a = around[j].as_ref()?;
                    translation(a, s).map(|t| (j, t))
                })
        });
        match shared {
            Some(found) => source.push(found),
            None => {
                by_area.entry(key).or_default().push(i);
                source.push((i, [0.0, 0.0]));
            }
        }
    }
    source
}

/// Plans of `regions` (each with its [`Others`]), in their order: see the module's doc. With
/// the copies `given`, those instead of the ones found: regions whose surroundings were
/// changed alike for each copy (their noise differs), copies found before the change.
pub fn plan_all(
    regions: &[(&Region, &Others)],
    below: &MultiPolygon<f64>,
    area: &MultiPolygon<f64>,
    widths: Widths,
    settings: &PoaSettings,
    start: [f64; 2],
    given: Option<&Sources>,
) -> Vec<Plan> {
    use rayon::prelude::*;
    let around: Vec<Option<Surroundings<'_>>> = regions
        .par_iter()
        .map(|(r, o)| surroundings(r, o, below, area, &widths))
        .collect();
    // Each region's source: itself, or an earlier representative and the translation.
    let source: Sources = match given {
        Some(g)
            if g.len() == regions.len()
                && g.iter()
                    .enumerate()
                    .all(|(i, s)| s.0 <= i && g[s.0].0 == s.0) =>
        {
            g.clone()
        }
        _ => sources_of(regions, &around),
    };
    let reps: Vec<usize> = (0..source.len()).filter(|&i| source[i].0 == i).collect();
    let plan_one = |i: usize| {
        let (r, o) = regions[i];
        // A region the polygon library fails on (an index out of bounds deep in geo's
        // booleans, on a cylinder's ring by Cura once) is left as sliced: the rest of the
        // file is still rewritten, and nothing is lost.
        std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            // The windows cut for the comparison are what the planner would cut again.
            match around[i].as_ref().and_then(|s| s.cut.as_ref()) {
                Some(win) => super::plan_in(r, win, o, widths, settings, start),
                None => plan(r, below, area, o, widths, settings, start),
            }
        }))
        .unwrap_or_else(|_| super::no_plan(MultiPolygon::new(Vec::new())))
    };
    let planned: Vec<Plan> = reps.par_iter().map(|&i| plan_one(i)).collect();
    // A representative's growth must have ended by itself, short of the bound its reach (or
    // its zone's extent) sets: a copy whose noisy reach sets another bound would grow the
    // same loops only then. Otherwise the copy is planned on its own.
    let w = widths.loop_width;
    let step = (1.0 - settings.overlap.clamp(0.05, 0.9)) * w;
    let free = |p: &Plan, a: &Region, b: &Region| {
        let md = a.max_distance.min(b.max_distance).min(1000.0);
        let extent = p
            .zone
            .bounding_rect()
            .map_or(0.0, |r| r.width().hypot(r.height()))
            .min(2000.0);
        let bound = if p.with_perimeter || p.ladder {
            extent
        } else {
            (md + widths.tolerance + 2.0 * w).max(extent)
        };
        ((p.loops + 3) as f64) * step < bound - 1.0
    };
    let alone: Vec<usize> = source
        .iter()
        .enumerate()
        .filter(|&(i, &(j, _))| {
            i != j && {
                let k = reps.binary_search(&j).expect("a representative");
                !free(&planned[k], regions[j].0, regions[i].0)
            }
        })
        .map(|(i, _)| i)
        .collect();
    let mut own: Vec<(usize, Plan)> = alone.par_iter().map(|&i| (i, plan_one(i))).collect();
    let mut out: Vec<Option<Plan>> = source
        .iter()
        .enumerate()
        .map(|(i, &(j, t))| {
            (i != j && alone.binary_search(&i).is_err()).then(|| {
                let k = reps.binary_search(&j).expect("a representative");
                translated(&planned[k], t)
            })
        })
        .collect();
    for (&i, p) in reps.iter().zip(planned) {
        out[i] = Some(p);
    }
    for (i, p) in own.drain(..) {
        out[i] = Some(p);
    }
    out.into_iter().flatten().collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::difference;
    use crate::geometry::testutil::{mp, rect};
    use crate::poa::testutil::overhang;
    use crate::poa::Strand;

    const W: f64 = 0.45;

    fn widths() -> Widths {
        Widths {
            loop_width: W,
            perimeter_width: W,
            tolerance: W / 2.0,
        }
    }

    /// A plate of mushrooms seen from above: a 6 mm square column under a 16 mm square cap,
    /// one per corner given, each cap's region with its own reach (copies' reaches differ by
    /// the noise of their sampling).
    fn plate(corners: &[([f64; 2], f64)]) -> (MultiPolygon<f64>, MultiPolygon<f64>, Vec<Region>) {
        let mut below = Vec::new();
        let mut area = Vec::new();
        let mut regions = Vec::new();
        for &([x, y], reach) in corners {
            let column = rect(x + 5.0, y + 5.0, x + 11.0, y + 11.0);
            let cap = rect(x, y, x + 16.0, y + 16.0);
            let r = difference(&mp(vec![cap.clone()]), &mp(vec![column.clone()]));
            regions.push(overhang(r.0[0].clone(), reach));
            below.push(column);
            area.push(cap);
        }
        (mp(below), mp(area), regions)
    }

    fn plans(below: &MultiPolygon<f64>, area: &MultiPolygon<f64>, regions: &[Region]) -> Vec<Plan> {
        let others = Others::default();
        let jobs: Vec<(&Region, &Others)> = regions.iter().map(|r| (r, &others)).collect();
        plan_all(
            &jobs,
            below,
            area,
            widths(),
            &PoaSettings::default(),
            [0.0, 0.0],
            None,
        )
    }

    fn alone(below: &MultiPolygon<f64>, area: &MultiPolygon<f64>, r: &Region) -> Plan {
        let settings = PoaSettings::default();
        plan(
            r,
            below,
            area,
            &Others::default(),
            widths(),
            &settings,
            [0.0, 0.0],
        )
    }

    fn points(p: &Plan) -> Vec<[f64; 2]> {
        p.strands.iter().flat_map(|s| s.points.clone()).collect()
    }

    #[test]
    fn a_copy_moved_on_the_plate_gets_the_plan_moved() {
        let (below, area, regions) = plate(&[([0.0, 0.0], 7.8), ([30.5, -40.25], 7.3)]);
        let got = plans(&below, &area, &regions);
        assert_eq!(got.len(), 2);
        assert!(got[0].loops >= 5, "loops {}", got[0].loops);
        // The first is planned as on its own; the second is its plan, moved.
        assert_eq!(points(&got[0]), points(&alone(&below, &area, &regions[0])));
        let (a, b) = (points(&got[0]), points(&got[1]));
        assert_eq!(a.len(), b.len());
        for (p, q) in a.iter().zip(&b) {
            assert!((p[0] + 30.5 - q[0]).abs() < 1e-9 && (p[1] - 40.25 - q[1]).abs() < 1e-9);
        }
        // What planning the copy on its own gives, up to where the loops start.
        let own = alone(&below, &area, &regions[1]);
        assert_eq!(own.loops, got[1].loops);
        let length = |p: &Plan| p.strands.iter().map(Strand::length).sum::<f64>();
        assert!(
            (length(&own) - length(&got[1])).abs() < 1e-3 * length(&own),
            "{} {} strands {} {}",
            length(&own),
            length(&got[1]),
            own.strands.len(),
            got[1].strands.len()
        );
        let zone = |p: &Plan| geo::Area::unsigned_area(&p.zone);
        // Booleans at another place on the plate round otherwise: float noise.
        assert!(
            (zone(&own) - zone(&got[1])).abs() < 1e-5 * zone(&own),
            "{} {}",
            zone(&own),
            zone(&got[1])
        );
    }

    #[test]
    fn parts_that_differ_or_stand_too_near_are_planned_on_their_own() {
        // The second column is 0.1 mm narrower: not a copy.
        let (mut below, area, mut regions) = plate(&[([0.0, 0.0], 7.8), ([40.0, 0.0], 7.8)]);
        below.0[1] = rect(45.0, 5.0, 50.9, 11.0);
        regions[1] = overhang(
            difference(&mp(vec![area.0[1].clone()]), &mp(vec![below.0[1].clone()])).0[0].clone(),
            7.8,
        );
        let got = plans(&below, &area, &regions);
        assert_eq!(points(&got[1]), points(&alone(&below, &area, &regions[1])));
        // Three copies in a row, 18 mm apart: the middle one's loops may reach as far as its
        // neighbours' columns, which it alone has on both sides.
        let (below, area, regions) =
            plate(&[([0.0, 0.0], 7.8), ([18.0, 0.0], 7.8), ([36.0, 0.0], 7.8)]);
        let got = plans(&below, &area, &regions);
        for (p, r) in got.iter().zip(&regions) {
            assert_eq!(points(p), points(&alone(&below, &area, r)));
        }
    }

    /// A ledge 8 mm deep off the side of a wall 80 mm long, at each corner given (a wall
    /// runs far past the planner's windows, which cut it), and extra posts below.
    fn ledges(
        corners: &[[f64; 2]],
        posts: &[Polygon<f64>],
    ) -> (MultiPolygon<f64>, MultiPolygon<f64>, Vec<Region>) {
        let (mut below, mut area, mut regions) = (Vec::new(), Vec::new(), Vec::new());
        for &[x, y] in corners {
            let wall = mp(vec![rect(x, y, x + 80.0, y + 6.0)]);
            let layer = crate::geometry::union(
                &wall,
                &mp(vec![rect(x + 35.0, y + 6.0, x + 45.0, y + 14.0)]),
            );
            let r = difference(&layer, &wall);
            regions.push(overhang(r.0[0].clone(), 8.0));
            below.extend(wall.0);
            area.extend(layer.0);
        }
        below.extend(posts.iter().cloned());
        (mp(below), mp(area), regions)
    }

    #[test]
    fn ledges_of_a_long_wall_share_a_plan_when_the_cut_windows_match() {
        let t = [3.2537891, 50.4962713];
        let (below, area, regions) = ledges(&[[0.0, 0.0], t], &[]);
        let got = plans(&below, &area, &regions);
        assert!(got[0].loops >= 5, "loops {}", got[0].loops);
        assert_eq!(points(&got[0]), points(&alone(&below, &area, &regions[0])));
        // The second is the first moved, rigidly, by the translation read off the cut
        // windows (their cut edges carry the regions' noise: within a micrometre).
        let (a, b) = (points(&got[0]), points(&got[1]));
        assert_eq!(a.len(), b.len());
        let moved = [b[0][0] - a[0][0], b[0][1] - a[0][1]];
        assert!((moved[0] - t[0]).abs() < 1e-3 && (moved[1] - t[1]).abs() < 1e-3);
        for (p, q) in a.iter().zip(&b) {
            assert!((p[0] + moved[0] - q[0]).abs() < 1e-9 && (p[1] + moved[1] - q[1]).abs() < 1e-9);
        }
        let own = alone(&below, &area, &regions[1]);
        assert_eq!(own.loops, got[1].loops);
        let length = |p: &Plan| p.strands.iter().map(Strand::length).sum::<f64>();
        assert!((length(&own) - length(&got[1])).abs() < 1e-3 * length(&own));
        // A post below beside the second ledge, within its window only: its plan is its own.
        let post = rect(t[0] + 30.0, t[1] + 10.0, t[0] + 32.0, t[1] + 12.0);
        let (below, area, regions) = ledges(&[[0.0, 0.0], t], &[post]);
        let got = plans(&below, &area, &regions);
        assert_eq!(points(&got[1]), points(&alone(&below, &area, &regions[1])));
    }
}
