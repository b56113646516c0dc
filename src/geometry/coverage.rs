//! How much of an area lies within reach of a set of polylines, by sampling.
//!
//! Input: a [`MultiPolygon`] (the area) and polylines, each with a reach (mm). Output: the
//! share of the area's sample points that lie within some polyline's reach, the points on a
//! square grid whose spacing is given (coarsened so that at most [`MAX_SAMPLES`] are taken).
//! Invariants: no polygon boolean or offset (the segments go into the proof's grid, which
//! bounds its cells): memory and time grow with the samples and the segments near them, never with how the strands' footprints overlap (a big cap's 140
//! overlapping loops cost the stroke buffer 70 ms, the sampling a fraction of that). The
//! answer is an estimate within the grid's resolution: use it to tell a plan that covers
//! its zone from one that leaves a good part of it, not for areas.

use geo::{BoundingRect, MultiPolygon};

use super::proof::{dist2, Grid, Seg};
use super::RingIndex;
use crate::layers::Role;

/// Most sample points taken over the area's box.
const MAX_SAMPLES: f64 = 40_000.0;

/// Share (0 to 1) of `area` within its reach of one of `lines` (each polyline with its reach,
/// mm), sampled every `spacing` mm. An area with no sample point inside gives 1.
pub fn share_within(area: &MultiPolygon<f64>, lines: &[(&[[f64; 2]], f64)], spacing: f64) -> f64 {
    let Some(b) = area.bounding_rect() else {
        return 1.0;
    };
    let (lo, hi) = (b.min(), b.max());
    let (w, h) = (hi.x - lo.x, hi.y - lo.y);
    if !(w.is_finite() && h.is_finite()) || spacing <= 0.0 || !spacing.is_finite() {
        return 1.0;
    }
    let spacing = spacing.max((w * h / MAX_SAMPLES).sqrt());
    // The polylines' segments in the proof's grid, each with its reach as its half width.
    let segs: Vec<Seg> = lines
        .iter()
        .filter(|(_, r)| r.is_finite() && *r >= 0.0)
        .flat_map(|&(pts, r)| {
            pts.windows(2).map(move |s| Seg {
                a: s[0],
                b: s[1],
                half: r,
                role: Role::Unknown,
                loop_at: None,
            })
        })
        .filter(|s| s.a.iter().chain(&s.b).all(|v| v.is_finite()))
        .collect();
    let reach = segs.iter().map(|s| s.half).fold(0.0_f64, f64::max);
    let grid = Grid::new(segs);
    let near = |q: [f64; 2]| grid.any_near(q, reach, |s| dist2(q, s) <= s.half * s.half);
    let inside = RingIndex::new(area);
    let (mut total, mut hit) = (0usize, 0usize);
    let rows = (h / spacing).floor() as usize + 1;
    for j in 0..rows {
        let y = lo.y + (j as f64 + 0.5) * spacing;
        if y > hi.y {
            break;
        }
        for (from, to) in inside.inside_intervals(&[[lo.x, y], [hi.x, y]]) {
            // Samples on the row's grid (not from each stretch's start), so that stretches
            // a hole apart are sampled alike.
            let mut k = (from / spacing - 0.5).ceil().max(0.0);
            while (k + 0.5) * spacing <= to {
                let q = [lo.x + (k + 0.5) * spacing, y];
                total += 1;
                hit += usize::from(near(q));
                k += 1.0;
            }
        }
    }
    if total == 0 {
        1.0
    } else {
        hit as f64 / total as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use geo::{coord, Rect};

    fn square(x0: f64, y0: f64, x1: f64, y1: f64) -> MultiPolygon<f64> {
        MultiPolygon::new(vec![Rect::new(
            coord! {x: x0, y: y0},
            coord! {x: x1, y: y1},
        )
        .to_polygon()])
    }

    #[test]
    fn a_strip_s_share_is_its_width_over_the_square_s() {
        // A 10 mm square; a line along x = 5 reaching 1 mm covers the strip 4..6: a fifth.
        let area = square(0.0, 0.0, 10.0, 10.0);
        let line = [[5.0, -1.0], [5.0, 11.0]];
        let share = share_within(&area, &[(&line[..], 1.0)], 0.05);
        assert!((share - 0.2).abs() < 0.01, "{share}");
        // Reaching 6 mm, it covers it all; no line, none of it.
        assert!((share_within(&area, &[(&line[..], 6.0)], 0.05) - 1.0).abs() < 1e-12);
        assert_eq!(share_within(&area, &[], 0.05), 0.0);
    }

    #[test]
    fn a_long_diagonal_is_found_along_its_whole_length_and_bad_numbers_are_skipped() {
        // Corner to corner of a 100 mm square, reaching 0.5 mm: a strip of 141 x 1 mm2 (the
        // square's box is sampled more coarsely than asked, 0.5 mm).
        let area = square(0.0, 0.0, 100.0, 100.0);
        let diagonal = [[0.0, 0.0], [100.0, 100.0]];
        let share = share_within(&area, &[(&diagonal[..], 0.5)], 0.05);
        assert!((share - 141.4 / 10_000.0).abs() < 0.002, "{share}");
        let bad = [[f64::NAN, 0.0], [1.0, f64::INFINITY]];
        let share = share_within(&area, &[(&bad[..], 1.0), (&diagonal[..], f64::NAN)], 0.05);
        assert_eq!(share, 0.0);
    }

    #[test]
    fn holes_are_not_sampled() {
        // A 10 mm square with a 6 mm hole: 64 mm2 of ring.
        let outer = Rect::new(coord! {x: 0.0, y: 0.0}, coord! {x: 10.0, y: 10.0}).to_polygon();
        let hole = Rect::new(coord! {x: 2.0, y: 2.0}, coord! {x: 8.0, y: 8.0}).to_polygon();
        let ring = MultiPolygon::new(vec![geo::Polygon::new(
            outer.exterior().clone(),
            vec![hole.exterior().clone()],
        )]);
        let line = [[5.0, 5.0], [5.0, 5.0 + 1e-9]];
        // Within 3 mm of the centre: the ring's parts within the disc of radius 3, i.e.
        // nothing (the hole's edge is 3 mm away at its nearest).
        let share = share_within(&ring, &[(&line[..], 2.9)], 0.05);
        assert!(share < 1e-9, "{share}");
        // Along the whole square's middle row, 1 mm either side: two 2 x 2 mm patches.
        let across = [[-1.0, 5.0], [11.0, 5.0]];
        let share = share_within(&ring, &[(&across[..], 1.0)], 0.05);
        assert!((share - 8.0 / 64.0).abs() < 0.01, "{share}");
    }
}
