//! A polygon set's boundary in a grid, for many point and polyline queries against one set.
//!
//! Input: a [`MultiPolygon`] (exteriors and holes, even-odd). Output: [`RingIndex`], which
//! tells whether a point lies inside the set and which stretches of a polyline do, exactly
//! (float intersections of the polyline's segments with the boundary segments), in time
//! proportional to the boundary segments near the query instead of all of them.
//! Invariants: the answers do not depend on the grid (it only narrows the segments tested);
//! memory is bounded by the cell cap whatever the set's extent.

use geo::MultiPolygon;

/// Most cells the grid holds: a set spanning a whole bed in fine cells gets bigger cells.
const MAX_CELLS: usize = 1 << 16;

/// The boundary segments of a polygon set, bucketed by grid cell.
#[derive(Debug, Default)]
pub struct RingIndex {
    segs: Vec<([f64; 2], [f64; 2])>,
    origin: [f64; 2],
    cell: f64,
    nx: usize,
    ny: usize,
    /// Cell `i` holds `items[start[i]..start[i + 1]]`.
    start: Vec<u32>,
    items: Vec<u32>,
}

impl RingIndex {
    pub fn new(set: &MultiPolygon<f64>) -> RingIndex {
        let mut segs = Vec::new();
        for poly in &set.0 {
            for ring in std::iter::once(poly.exterior()).chain(poly.interiors()) {
                for w in ring.0.windows(2) {
                    let (a, b) = ([w[0].x, w[0].y], [w[1].x, w[1].y]);
                    if a != b && a.iter().chain(&b).all(|v| v.is_finite()) {
                        segs.push((a, b));
                    }
                }
            }
        }
        if segs.is_empty() {
            return RingIndex::default();
        }
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        for (a, b) in &segs {
            for p in [a, b] {
                lo = [lo[0].min(p[0]), lo[1].min(p[1])];
                hi = [hi[0].max(p[0]), hi[1].max(p[1])];
            }
        }
        let (w, h) = ((hi[0] - lo[0]).max(1e-9), (hi[1] - lo[1]).max(1e-9));
        // About one segment per cell, within the cap.
        let cells = segs.len().clamp(1, MAX_CELLS) as f64;
        let cell = ((w * h / cells).sqrt()).max(w.max(h) / MAX_CELLS as f64 * 4.0);
        let nx = ((w / cell) as usize + 1).min(MAX_CELLS);
        let ny = ((h / cell) as usize + 1).min(MAX_CELLS / nx.max(1)).max(1);
        let cell = cell.max(w / nx as f64).max(h / ny as f64) * (1.0 + 1e-9);
        let mut index = RingIndex {
            segs,
            origin: lo,
            cell,
            nx,
            ny,
            start: Vec::new(),
            items: Vec::new(),
        };
        let mut entries: Vec<(u32, u32)> = Vec::new();
        for (i, &(a, b)) in index.segs.iter().enumerate() {
            index.cells_of(a, b, |c| entries.push((c as u32, i as u32)));
        }
        (index.start, index.items) = super::buckets(nx * ny, &entries);
        index
    }

    fn col(&self, x: f64) -> usize {
        super::cell_of(x, self.origin[0], self.cell, self.nx)
    }

    fn row(&self, y: f64) -> usize {
        super::cell_of(y, self.origin[1], self.cell, self.ny)
    }

    /// Calls `f` with every cell the segment's box covers (a segment is short next to the
    /// set, so its box is few cells).
    fn cells_of(&self, a: [f64; 2], b: [f64; 2], mut f: impl FnMut(usize)) {
        let (x0, x1) = (self.col(a[0].min(b[0])), self.col(a[0].max(b[0])));
        let (y0, y1) = (self.row(a[1].min(b[1])), self.row(a[1].max(b[1])));
        for iy in y0..=y1 {
            for ix in x0..=x1 {
                f(iy * self.nx + ix);
            }
        }
    }

    fn cell_items(&self, c: usize) -> &[u32] {
        &self.items[self.start[c] as usize..self.start[c + 1] as usize]
    }

    /// Whether `q` lies inside the set and off its boundary: what geo's `contains` answers
    /// for a polygon set (its robust orientation test for the boundary, here only against
    /// the segments of `q`'s cell, which hold every segment through `q`).
    pub fn contains_strictly(&self, q: [f64; 2]) -> bool {
        use geo::kernels::{Kernel, Orientation, RobustKernel};
        if self.segs.is_empty() || !(q[0].is_finite() && q[1].is_finite()) {
            return false;
        }
        let (hi_x, hi_y) = (
            self.origin[0] + self.cell * self.nx as f64,
            self.origin[1] + self.cell * self.ny as f64,
        );
        if q[0] < self.origin[0] || q[1] < self.origin[1] || q[0] > hi_x || q[1] > hi_y {
            return false;
        }
        let c = self.row(q[1]) * self.nx + self.col(q[0]);
        let p = geo::coord! {x: q[0], y: q[1]};
        let on = self.cell_items(c).iter().any(|&i| {
            let (a, b) = self.segs[i as usize];
            q[0] >= a[0].min(b[0])
                && q[0] <= a[0].max(b[0])
                && q[1] >= a[1].min(b[1])
                && q[1] <= a[1].max(b[1])
                && RobustKernel::orient2d(
                    geo::coord! {x: a[0], y: a[1]},
                    geo::coord! {x: b[0], y: b[1]},
                    p,
                ) == Orientation::Collinear
        });
        if on {
            return false;
        }
        // A ray to +x, each crossing decided by the robust orientation (a point 1e-16 off a
        // slanted edge is where geo says it is) and each segment counted once, whichever of
        // its cells it is met in.
        let mut crossing: Vec<u32> = Vec::new();
        let iy = self.row(q[1]);
        for ix in self.col(q[0])..self.nx {
            for &i in self.cell_items(iy * self.nx + ix) {
                let (a, b) = self.segs[i as usize];
                if (a[1] > q[1]) != (b[1] > q[1]) {
                    let (u, v) = if a[1] > q[1] { (b, a) } else { (a, b) };
                    let left = RobustKernel::orient2d(
                        geo::coord! {x: u[0], y: u[1]},
                        geo::coord! {x: v[0], y: v[1]},
                        p,
                    ) == Orientation::CounterClockwise;
                    if left {
                        crossing.push(i);
                    }
                }
            }
        }
        crossing.sort_unstable();
        crossing.dedup();
        crossing.len() % 2 == 1
    }

    /// [`RingIndex::contains_strictly`] for the points `a + t (b - a)`, `t` in `ts`
    /// (increasing), pushed to `out`: asked once or twice per stretch between the points
    /// where the boundary meets the segment, not once per point. Points next to such a meeting
    /// are asked one by one, and so are all of them where the boundary runs along the segment
    /// or a stretch's two ends disagree. A damaged file's region (a strand to X 99999) has a
    /// boundary of 100 m sampled every 0.2 mm, each sample a ray over a grid of metre cells.
    pub fn contains_strictly_along(
        &self,
        a: [f64; 2],
        b: [f64; 2],
        ts: &[f64],
        out: &mut Vec<bool>,
    ) {
        use geo::kernels::{Kernel, Orientation, RobustKernel};
        let at = |t: f64| [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])];
        let finite = a.iter().chain(&b).all(|v| v.is_finite());
        if self.segs.is_empty() || !finite || ts.len() < 3 {
            out.extend(ts.iter().map(|&t| self.contains_strictly(at(t))));
            return;
        }
        let (ca, cb) = (
            geo::coord! {x: a[0], y: a[1]},
            geo::coord! {x: b[0], y: b[1]},
        );
        let mut cuts: Vec<f64> = Vec::new();
        let mut along = false;
        self.cells_of(a, b, |c| {
            for &i in self.cell_items(c) {
                let (p, q) = self.segs[i as usize];
                let (cp, cq) = (
                    geo::coord! {x: p[0], y: p[1]},
                    geo::coord! {x: q[0], y: q[1]},
                );
                let (o1, o2) = (
                    RobustKernel::orient2d(ca, cb, cp),
                    RobustKernel::orient2d(ca, cb, cq),
                );
                if o1 == Orientation::Collinear && o2 == Orientation::Collinear {
                    along = true;
                    continue;
                }
                if o1 == o2 {
                    continue;
                }
                let (o3, o4) = (
                    RobustKernel::orient2d(cp, cq, ca),
                    RobustKernel::orient2d(cp, cq, cb),
                );
                if o3 == o4 && o3 != Orientation::Collinear {
                    continue;
                }
                let (r, s) = ([b[0] - a[0], b[1] - a[1]], [q[0] - p[0], q[1] - p[1]]);
                let d = [p[0] - a[0], p[1] - a[1]];
                let t = (d[0] * s[1] - d[1] * s[0]) / (r[0] * s[1] - r[1] * s[0]);
                cuts.push(if t.is_finite() {
                    t.clamp(0.0, 1.0)
                } else {
                    0.0
                });
            }
        });
        if along {
            out.extend(ts.iter().map(|&t| self.contains_strictly(at(t))));
            return;
        }
        cuts.sort_by(f64::total_cmp);
        // Within NEAR of a meeting a point is asked alone (the meeting's parameter is a
        // float); the stretches between are asked at both ends.
        const NEAR: f64 = 1e-6;
        let mut k = 0;
        let mut c = 0;
        while k < ts.len() {
            while c < cuts.len() && cuts[c] < ts[k] - NEAR {
                c += 1;
            }
            if c < cuts.len() && cuts[c] <= ts[k] + NEAR {
                out.push(self.contains_strictly(at(ts[k])));
                k += 1;
                continue;
            }
            // The stretch: points before the next meeting's neighbourhood.
            let end = match cuts.get(c) {
                Some(&t) => k + ts[k..].partition_point(|&u| u < t - NEAR),
                None => ts.len(),
            };
            let first = self.contains_strictly(at(ts[k]));
            let last = if end - 1 > k {
                self.contains_strictly(at(ts[end - 1]))
            } else {
                first
            };
            if first == last {
                out.extend(std::iter::repeat_n(first, end - k));
            } else {
                out.extend(ts[k..end].iter().map(|&t| self.contains_strictly(at(t))));
            }
            k = end;
        }
    }

    /// Whether the set has no boundary (no area).
    pub fn is_empty(&self) -> bool {
        self.segs.is_empty()
    }

    /// Whether `q` lies inside the set (even-odd rule; a point on the boundary may go
    /// either way).
    pub fn contains(&self, q: [f64; 2]) -> bool {
        if self.segs.is_empty() || !(q[0].is_finite() && q[1].is_finite()) {
            return false;
        }
        let (lo_y, hi_y) = (self.origin[1], self.origin[1] + self.cell * self.ny as f64);
        if q[1] < lo_y || q[1] > hi_y || q[0] > self.origin[0] + self.cell * self.nx as f64 {
            return false;
        }
        // A ray to +x: each segment crossing it counts once, in the cell where it crosses.
        let iy = self.row(q[1]);
        let mut inside = false;
        for ix in self.col(q[0])..self.nx {
            let c = iy * self.nx + ix;
            for &i in self.cell_items(c) {
                let (a, b) = self.segs[i as usize];
                if (a[1] > q[1]) != (b[1] > q[1]) {
                    let x = a[0] + (q[1] - a[1]) / (b[1] - a[1]) * (b[0] - a[0]);
                    if x > q[0] && self.col(x) == ix {
                        inside = !inside;
                    }
                }
            }
        }
        inside
    }

    /// The stretches of the polyline `pts` inside the set, as (from, to) distances along it,
    /// in order and apart. Each segment is cut where it crosses the boundary and each piece
    /// judged by its middle point.
    pub fn inside_intervals(&self, pts: &[[f64; 2]]) -> Vec<(f64, f64)> {
        let mut out: Vec<(f64, f64)> = Vec::new();
        let mut along = 0.0;
        let mut cuts: Vec<f64> = Vec::new();
        for w in pts.windows(2) {
            let (a, b) = (w[0], w[1]);
            let len = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt();
            if len <= 0.0 || !len.is_finite() {
                continue;
            }
            cuts.clear();
            cuts.push(0.0);
            if !self.segs.is_empty() {
                let mut seen: Vec<u32> = Vec::new();
                self.cells_of(a, b, |c| {
                    for &i in self.cell_items(c) {
                        if seen.contains(&i) {
                            continue;
                        }
                        seen.push(i);
                        let (p, q) = self.segs[i as usize];
                        if let Some(t) = crossing(a, b, p, q) {
                            cuts.push(t);
                        }
                    }
                });
            }
            cuts.push(1.0);
            cuts.sort_by(f64::total_cmp);
            for k in 0..cuts.len() - 1 {
                let (t0, t1) = (cuts[k], cuts[k + 1]);
                if t1 - t0 <= 0.0 {
                    continue;
                }
                let tm = (t0 + t1) / 2.0;
                let mid = [a[0] + tm * (b[0] - a[0]), a[1] + tm * (b[1] - a[1])];
                if self.contains(mid) {
                    let (s0, s1) = (along + t0 * len, along + t1 * len);
                    match out.last_mut() {
                        Some(last) if (s0 - last.1).abs() <= 1e-12 => last.1 = s1,
                        _ => out.push((s0, s1)),
                    }
                }
            }
            along += len;
        }
        out
    }
}

/// Where on `a`-`b` (parameter in 0..=1) the segment `p`-`q` meets it, if it does at one
/// point (parallel segments give none: the pieces around them are judged by their middles).
fn crossing(a: [f64; 2], b: [f64; 2], p: [f64; 2], q: [f64; 2]) -> Option<f64> {
    let r = [b[0] - a[0], b[1] - a[1]];
    let s = [q[0] - p[0], q[1] - p[1]];
    let denom = r[0] * s[1] - r[1] * s[0];
    // |denom| <= 1e-15 |r| |s|, squared: most pairs asked do not cross, and two `hypot`s
    // per pair were a sixth of a plate's cap layer's rewrite.
    let (rr, ss) = (r[0] * r[0] + r[1] * r[1], s[0] * s[0] + s[1] * s[1]);
    if denom * denom <= 1e-30 * (rr * ss) {
        return None;
    }
    let d = [p[0] - a[0], p[1] - a[1]];
    let t = (d[0] * s[1] - d[1] * s[0]) / denom;
    let u = (d[0] * r[1] - d[1] * r[0]) / denom;
    ((0.0..=1.0).contains(&t) && (0.0..=1.0).contains(&u)).then_some(t)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::testutil::{mp, rect};

    /// A 10 mm square with a 2 mm square hole in its middle.
    fn square_with_hole() -> geo::Polygon<f64> {
        let mut outer = rect(0.0, 0.0, 10.0, 10.0);
        outer.interiors_push(vec![
            (4.0, 4.0),
            (6.0, 4.0),
            (6.0, 6.0),
            (4.0, 6.0),
            (4.0, 4.0),
        ]);
        outer
    }

    #[test]
    fn points_and_stretches_inside_a_square_with_a_hole() {
        let outer = square_with_hole();
        let set = mp(vec![outer]);
        let idx = RingIndex::new(&set);
        assert!(idx.contains([1.0, 1.0]));
        assert!(!idx.contains([5.0, 5.0]));
        assert!(!idx.contains([11.0, 5.0]));
        assert!(!idx.contains([-1.0, 5.0]));
        let iv = idx.inside_intervals(&[[-1.0, 5.0], [11.0, 5.0]]);
        let want = [(1.0, 5.0), (7.0, 11.0)];
        assert_eq!(iv.len(), 2, "{iv:?}");
        for (g, w) in iv.iter().zip(want) {
            assert!(
                (g.0 - w.0).abs() < 1e-9 && (g.1 - w.1).abs() < 1e-9,
                "{iv:?}"
            );
        }
        // A polyline turning inside keeps one stretch across its corner.
        let iv = idx.inside_intervals(&[[1.0, 1.0], [3.0, 1.0], [3.0, 3.0]]);
        assert_eq!(iv.len(), 1);
        assert!((iv[0].1 - 4.0).abs() < 1e-9);
        // Through a vertex of the hole: the pieces are judged by their middles.
        let iv = idx.inside_intervals(&[[2.0, 2.0], [8.0, 8.0]]);
        let inside: f64 = iv.iter().map(|(a, b)| b - a).sum();
        assert!((inside - 8f64.sqrt() * 2.0).abs() < 1e-9, "{iv:?}");
    }

    #[test]
    fn points_along_a_segment_are_judged_as_one_by_one() {
        // Segments across the square with a hole and a slanted triangle: through vertices,
        // along edges, ending on them, long and short, sampled finely and coarsely.
        let tri = geo::Polygon::new(
            vec![(12.0, 0.0), (19.0, 3.0), (12.0, 7.0), (12.0, 0.0)].into(),
            Vec::new(),
        );
        let set = mp(vec![square_with_hole(), tri]);
        let idx = RingIndex::new(&set);
        let mut segs: Vec<([f64; 2], [f64; 2])> = vec![
            ([-1.0, 5.0], [21.0, 5.0]),
            ([0.0, 0.0], [10.0, 10.0]),
            ([4.0, -1.0], [4.0, 11.0]),
            ([0.0, 4.0], [20.0, 4.0]),
            ([12.0, 0.0], [19.0, 3.0]),
            ([5.0, 5.0], [5.0, 5.0]),
            ([-3.0, -3.0], [25.0, 9.0]),
            ([19.0, 3.0], [-1.0, 3.0]),
        ];
        for i in 0..40 {
            let f = i as f64;
            segs.push(([f * 0.55 - 2.0, -1.0], [21.0 - f * 0.5, 8.0 + f * 0.07]));
            segs.push(([6.0, f * 0.25], [6.0 + f * 0.3, 11.0 - f * 0.25]));
        }
        // Sampled at the middles of n pieces, and at parameters landing on the boundary.
        let mut params: Vec<Vec<f64>> = [1, 3, 7, 50, 997]
            .iter()
            .map(|&n| (0..n).map(|k| (k as f64 + 0.5) / n as f64).collect())
            .collect();
        params.push((0..=100).map(|k| k as f64 / 100.0).collect());
        for (a, b) in segs {
            for ts in &params {
                let mut got = Vec::new();
                idx.contains_strictly_along(a, b, ts, &mut got);
                let want: Vec<bool> = ts
                    .iter()
                    .map(|&t| {
                        idx.contains_strictly([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])])
                    })
                    .collect();
                assert_eq!(got, want, "{a:?} {b:?} {}", ts.len());
            }
        }
    }

    #[test]
    fn strictly_inside_agrees_with_geo_on_and_off_the_boundary() {
        use geo::Contains;
        // A square with a hole and a slanted triangle: grid points fall on the horizontal and
        // vertical edges and on the vertices; points on the slanted edge are made on it.
        let outer = square_with_hole();
        let tri = geo::Polygon::new(
            vec![(12.0, 0.0), (19.0, 3.0), (12.0, 7.0), (12.0, 0.0)].into(),
            Vec::new(),
        );
        let set = mp(vec![outer, tri]);
        let idx = RingIndex::new(&set);
        let mut points: Vec<[f64; 2]> = Vec::new();
        for i in -2..=42 {
            for j in -2..=22 {
                points.push([i as f64 * 0.5, j as f64 * 0.5]);
            }
        }
        for k in 0..=20 {
            let t = k as f64 / 20.0;
            points.push([12.0 + 7.0 * t, 3.0 * t]);
            points.push([19.0 - 7.0 * t, 3.0 + 4.0 * t]);
            // And a few ulps either side of the slanted edges.
            for d in [-4e-15, -1e-15, 1e-15, 4e-15] {
                points.push([12.0 + 7.0 * t, 3.0 * t + d]);
                points.push([19.0 - 7.0 * t + d, 3.0 + 4.0 * t]);
            }
        }
        let mut on_boundary = 0;
        for q in points {
            let want = set.contains(&geo::Point::new(q[0], q[1]));
            assert_eq!(idx.contains_strictly(q), want, "{q:?}");
            on_boundary += usize::from(!want && idx.contains(q));
        }
        // Some boundary points the even-odd test alone takes for inside.
        assert!(on_boundary > 0);
    }
}
