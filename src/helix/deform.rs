//! The deformation of a helix (Kanada's `deform_cylinder` / `deform_xyz`): every point of
//! the helix mapped by three expressions, its cross-section and speed by two more.
//!
//! Input: the [`Helix`] of a spiral-vase file and a [`Spec`] (frame, position expressions,
//! cross-section and speed expressions, named parameters). Output: a [`Deform`], a
//! [`MoveMap`] that [`crate::movemap::apply`] runs over the file.
//!
//! The mapping (state in the README):
//! - Coordinates are relative to the centre (default: the helix's axis): `x`, `y`, `r`,
//!   `theta` (radians) and `z` = height above the *end of the helix's first turn*.
//! - Everything before the helix (first layer, solid bottom) is kept as sliced. The first
//!   turn (which slicers lay on the bottom, with an extrusion ramp) is blended from the
//!   input point to the mapped point at `z = 0`, so the mapping starts on top of it and a
//!   dish's `0.3 z` never squeezes a turn onto the bottom.
//! - Output Z = Z at the end of the first turn + the third expression.
//! - Moves are subdivided until the midpoint of each output piece is within `chord` of the
//!   mapped midpoint of its input piece; arcs are linearised first.
//! - E of each output piece = mapped cross-section x its 3D length / filament area, where
//!   the input cross-section `c` = E x filament area / 3D length of the input move; without
//!   `--cross-section` the bead keeps its cross-section (E per mm as sliced).
//! - F = 60 x the mapped speed `v` (mm/s); without `--speed` the file's F.
//! - Moves after the helix near the part (a slicer's last flat part-turn, a wipe: within
//!   1.5 r0 + 5 mm of the axis) are mapped like the helix's top, heights above it kept;
//!   moves farther away (park, end lift) keep their XY and are raised by how much higher
//!   the deformed top is than the sliced one, never lowered; relative (G91) moves are kept.

use crate::error::Error;
use crate::expr::{Expr, ExprError};
use crate::helix::Helix;
use crate::machine::{Machine, Move};
use crate::movemap::{MoveMap, Piece};
use crate::writer::MmPerMin;

/// The coordinate frame the position expressions are written in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Frame {
    /// `R;THETA;Z` from `x, y, z, r, theta`.
    Cylindrical,
    /// `X;Y;Z` from the same variables.
    Cartesian,
}

/// What the user asked for.
#[derive(Debug, Clone, PartialEq)]
pub struct Spec {
    pub frame: Frame,
    pub position: [String; 3],
    pub cross_section: Option<String>,
    pub speed: Option<String>,
    pub params: Vec<(String, f64)>,
    pub center: Option<[f64; 2]>,
    /// Largest distance of an output piece's midpoint from the mapping (mm).
    pub chord: f64,
    /// Name of the preset, when one was used.
    pub preset: Option<String>,
}

/// Variables of the position expressions, in the order values are given.
pub const POSITION_VARS: &[&str] = &["x", "y", "z", "r", "theta"];
/// Variables of the cross-section expression.
pub const SECTION_VARS: &[&str] = &["c", "x", "y", "z", "r", "theta"];
/// Variables of the speed expression.
pub const SPEED_VARS: &[&str] = &["v", "x", "y", "z", "r", "theta"];

/// A built-in deformation: name, frame, expressions, parameters with defaults, description.
pub struct Preset {
    pub name: &'static str,
    pub position: [&'static str; 3],
    pub params: &'static [(&'static str, f64, &'static str)],
    pub about: &'static str,
}

/// The presets of the paper, in the forms poa implements.
pub const PRESETS: &[Preset] = &[
    Preset {
        name: "dish",
        position: ["r + k*z", "theta", "s*z"],
        params: &[
            ("k", 1.05, "outward step per mm of input height"),
            ("s", 0.3, "output height per mm of input height"),
        ],
        about: "a shallow dish: the wall leans atan(k/s) = 74 deg from the vertical",
    },
    Preset {
        name: "vase",
        position: ["r*(a + b*sin(z/w + ph))/(a + b*sin(ph))", "theta", "z"],
        params: &[
            ("a", 0.8, "mean radius factor"),
            ("b", 0.4, "bulge amplitude (radius factor)"),
            ("w", 8.0, "wavelength / (2 pi), mm of height"),
            ("ph", 6.5, "phase (radians)"),
        ],
        about: "a bulging vase: radius r (a + b sin(z/w + ph)) / (a + b sin(ph)), the paper's \
                profile scaled to start at the sliced radius (no step at the bottom)",
    },
    Preset {
        name: "sphere",
        position: [
            "R*sin(phi0 + z/R)*r/r0",
            "theta",
            "R*(cos(phi0) - cos(phi0 + z/R))",
        ],
        params: &[
            (
                "R",
                0.0,
                "sphere radius, mm (0: chosen so that the top edge is at `top`)",
            ),
            (
                "top",
                150.0,
                "polar angle of the top edge when R is chosen, degrees",
            ),
        ],
        about: "a sphere of radius R through the bottom's edge: the polar angle grows from \
                phi0 = asin(r0/R) by z/R, so turns keep their spacing along the surface",
    },
];

impl Spec {
    /// A preset with user parameters (`k=v`) over its defaults.
    pub fn preset(name: &str, overrides: &[(String, f64)]) -> Result<Spec, Error> {
        let Some(p) = PRESETS.iter().find(|p| p.name == name) else {
            let names: Vec<&str> = PRESETS.iter().map(|p| p.name).collect();
            return Err(Error::Invalid(format!(
                "unknown preset `{name}`; the presets are {}",
                names.join(", ")
            )));
        };
        let mut params: Vec<(String, f64)> = p
            .params
            .iter()
            .map(|(k, v, _)| (k.to_string(), *v))
            .collect();
        for (k, v) in overrides {
            match params.iter_mut().find(|(n, _)| n == k) {
                Some(slot) => slot.1 = *v,
                None => {
                    let known: Vec<&str> = p.params.iter().map(|q| q.0).collect();
                    return Err(Error::Invalid(format!(
                        "preset {name} has no parameter `{k}`; its parameters are {}",
                        known.join(", ")
                    )));
                }
            }
        }
        Ok(Spec {
            frame: Frame::Cylindrical,
            position: p.position.map(str::to_string),
            cross_section: None,
            speed: None,
            params,
            center: None,
            chord: 0.01,
            preset: Some(name.to_string()),
        })
    }

    /// Free expressions `A;B;C` in `frame`.
    pub fn expressions(frame: Frame, text: &str, params: &[(String, f64)]) -> Result<Spec, Error> {
        let parts: Vec<&str> = text.split(';').collect();
        if parts.len() != 3 {
            return Err(Error::Invalid(format!(
                "`{text}` has {} parts; give three expressions separated by `;` ({})",
                parts.len(),
                match frame {
                    Frame::Cylindrical => "R;THETA;Z",
                    Frame::Cartesian => "X;Y;Z",
                }
            )));
        }
        Ok(Spec {
            frame,
            position: [parts[0], parts[1], parts[2]].map(|s| s.trim().to_string()),
            cross_section: None,
            speed: None,
            params: params.to_vec(),
            center: None,
            chord: 0.01,
            preset: None,
        })
    }
}

/// A compiled deformation of one helix.
pub struct Deform {
    helix: Helix,
    frame: Frame,
    center: [f64; 2],
    position: [Expr; 3],
    section: Option<Expr>,
    speed: Option<Expr>,
    chord: f64,
    filament_area: f64,
    /// Z where the mapping's z = 0 (end of the first turn).
    z_base: f64,
    /// Mapped Z of the helix's last point, once reached.
    top_out: Option<f64>,
    /// The first value no print can use (NaN, negative cross-section, speed <= 0).
    problem: Option<String>,
    /// Output pieces written for the helix.
    pub pieces: u64,
}

fn expr_error(which: &str, text: &str, e: ExprError) -> Error {
    Error::Invalid(format!("{which} `{text}`, {e}"))
}

impl Deform {
    /// Compiles `spec` for `helix`; `filament_area` in mm2.
    pub fn new(spec: &Spec, helix: &Helix, filament_area: f64) -> Result<Deform, Error> {
        if !(1e-4..=1.0).contains(&spec.chord) {
            return Err(Error::Invalid(format!(
                "--chord {} is out of range 0.0001..1 mm",
                spec.chord
            )));
        }
        let center = spec.center.unwrap_or(helix.center);
        let height = (helix.z_top - helix.z0 - helix.pitch).max(helix.pitch);
        let mut params: Vec<(String, f64)> = vec![
            ("H".into(), height),
            ("r0".into(), helix.r0),
            ("p".into(), helix.pitch),
        ];
        for (k, v) in &spec.params {
            if !v.is_finite() {
                return Err(Error::Invalid(format!(
                    "parameter {k} = {v} is not a number"
                )));
            }
            if POSITION_VARS.contains(&k.as_str()) || k == "c" || k == "v" || k == "pi" {
                return Err(Error::Invalid(format!(
                    "parameter name `{k}` is taken by a variable; choose another name"
                )));
            }
            match params.iter_mut().find(|(n, _)| n == k) {
                Some(slot) => slot.1 = *v,
                None => params.push((k.clone(), *v)),
            }
        }
        if spec.preset.as_deref() == Some("sphere") {
            let top = params
                .iter()
                .find(|(n, _)| n == "top")
                .map_or(150.0, |p| p.1)
                .to_radians();
            let r0 = helix.r0;
            let r = params.iter_mut().find(|(n, _)| n == "R").unwrap();
            if r.1 == 0.0 {
                // The arc from phi0 = asin(r0/R) to `top` as long as the helix is tall:
                // R (top - asin(r0/R)) = H, which grows with R; R = r0 when even the
                // equator-up arc is longer than H.
                let arc = |big: f64| big * (top - (r0 / big).min(1.0).asin());
                let (mut lo, mut hi) = (r0, r0 * 1000.0);
                if arc(lo) < height {
                    for _ in 0..100 {
                        let mid = (lo + hi) / 2.0;
                        if arc(mid) < height {
                            lo = mid;
                        } else {
                            hi = mid;
                        }
                    }
                }
                r.1 = lo;
            }
            let big_r = r.1;
            if big_r < r0 {
                return Err(Error::Invalid(format!(
                    "sphere radius R = {big_r} mm is smaller than the vase's radius {r0:.2} mm; give R >= r0"
                )));
            }
            params.push(("phi0".into(), (r0 / big_r).min(1.0).asin()));
        }
        let refs: Vec<(&str, f64)> = params.iter().map(|(k, v)| (k.as_str(), *v)).collect();
        let names = match spec.frame {
            Frame::Cylindrical => ["R (radius)", "THETA (angle)", "Z (height)"],
            Frame::Cartesian => ["X", "Y", "Z"],
        };
        let compile = |i: usize| {
            Expr::compile(&spec.position[i], POSITION_VARS, &refs)
                .map_err(|e| expr_error(names[i], &spec.position[i], e))
        };
        let position = [compile(0)?, compile(1)?, compile(2)?];
        let section = spec
            .cross_section
            .as_deref()
            .map(|t| {
                Expr::compile(t, SECTION_VARS, &refs)
                    .map_err(|e| expr_error("--cross-section", t, e))
            })
            .transpose()?;
        let speed = spec
            .speed
            .as_deref()
            .map(|t| Expr::compile(t, SPEED_VARS, &refs).map_err(|e| expr_error("--speed", t, e)))
            .transpose()?;
        Ok(Deform {
            helix: helix.clone(),
            frame: spec.frame,
            center,
            position,
            section,
            speed,
            chord: spec.chord,
            filament_area,
            z_base: helix.z0 + helix.pitch,
            top_out: None,
            problem: None,
            pieces: 0,
        })
    }

    /// The variables `x, y, z, r, theta` of an input point of the helix.
    fn vars(&self, p: [f64; 3]) -> [f64; 5] {
        let (x, y) = (p[0] - self.center[0], p[1] - self.center[1]);
        [x, y, (p[2] - self.z_base).max(0.0), x.hypot(y), y.atan2(x)]
    }

    fn mapped(&self, v: [f64; 5]) -> [f64; 3] {
        let a = self.position[0].eval(&v);
        let b = self.position[1].eval(&v);
        let c = self.position[2].eval(&v);
        let (x, y) = match self.frame {
            Frame::Cylindrical => (a * b.cos(), a * b.sin()),
            Frame::Cartesian => (a, b),
        };
        [self.center[0] + x, self.center[1] + y, self.z_base + c]
    }

    /// Where the mapping puts an input point of the helix.
    pub fn point(&self, p: [f64; 3]) -> [f64; 3] {
        let v = self.vars(p);
        let s = p[2] - self.helix.z0;
        if s >= self.helix.pitch {
            return self.mapped(v);
        }
        // First turn: blended from the point as sliced to the mapping at z = 0.
        let t = (s / self.helix.pitch).clamp(0.0, 1.0);
        let m = self.mapped(v);
        [0, 1, 2].map(|i| (1.0 - t) * p[i] + t * m[i])
    }

    /// The first unusable value met, if any (checked after the file is mapped).
    pub fn problem(&self) -> Option<&str> {
        self.problem.as_deref()
    }

    fn note(&mut self, what: impl FnOnce() -> String) {
        if self.problem.is_none() {
            self.problem = Some(what());
        }
    }

    /// Pieces of the input segment a -> b (3D, parameters 0..1) into `out` as end points
    /// with the input parameter of each.
    fn subdivide(&self, a: [f64; 3], b: [f64; 3], out: &mut Vec<([f64; 3], f64)>) {
        let lerp = |u: f64| [0, 1, 2].map(|i| a[i] + (b[i] - a[i]) * u);
        let mut stack = vec![(0.0f64, 1.0f64, self.point(a), self.point(b), 0u32)];
        // Depth-first, right half pushed first, so pieces come out in order.
        while let Some((u0, u1, p0, p1, depth)) = stack.pop() {
            let um = (u0 + u1) / 2.0;
            let pm = self.point(lerp(um));
            let mid = [0, 1, 2].map(|i| (p0[i] + p1[i]) / 2.0);
            let off =
                ((pm[0] - mid[0]).powi(2) + (pm[1] - mid[1]).powi(2) + (pm[2] - mid[2]).powi(2))
                    .sqrt();
            if off > self.chord && depth < 16 {
                stack.push((um, u1, pm, p1, depth + 1));
                stack.push((u0, um, p0, pm, depth + 1));
            } else {
                out.push((p1, u1));
            }
        }
    }
}

/// Most moves a deformation writes (the file is made in memory, about 50 bytes a move).
pub const MAX_PIECES: u64 = 5_000_000;

fn before_relative(m: &Machine) -> bool {
    m.xyz_relative()
}

fn dist3(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

impl MoveMap for Deform {
    fn map(&mut self, m: &Move, _before: &Machine, out: &mut Vec<Piece>) {
        if self.pieces > MAX_PIECES {
            // Refused after the pass (see `problem`): the rest is not worth mapping.
            out.push(Piece::unchanged(m));
            return;
        }
        if m.line < self.helix.first_line {
            out.push(Piece::unchanged(m));
            return;
        }
        if m.line > self.helix.last_line && before_relative(_before) {
            // Relative moves (a G91 end script) move by the same amount from wherever the
            // deformed print ended.
            out.push(Piece::unchanged(m));
            return;
        }
        if m.line > self.helix.last_line {
            let near = self.vars(m.to)[3] <= 1.5 * self.helix.r0 + 5.0;
            if near {
                // Near the part (a slicer's last flat part-turn, a wipe): mapped like the
                // helix's top, heights above it kept.
                let top = [m.to[0], m.to[1], self.helix.z_top];
                let p = self.point(top);
                let c = if m.e > 0.0 {
                    let l = m.xy_length().hypot(m.to[2] - m.from[2]).max(1e-9);
                    m.e / l
                } else {
                    0.0
                };
                let from = self.point([m.from[0], m.from[1], self.helix.z_top]);
                let to = [p[0], p[1], p[2] + (m.to[2] - self.helix.z_top).max(0.0)];
                let e = if m.e > 0.0 { c * dist3(from, to) } else { m.e };
                out.push(Piece {
                    to,
                    e,
                    feed: MmPerMin(m.feed),
                });
                return;
            }
            // Far from the part (park, end lift): never lower than the deformed top.
            let lift = self
                .top_out
                .map_or(0.0, |t| (t - self.helix.z_top).max(0.0));
            let mut p = Piece::unchanged(m);
            p.to[2] += lift;
            out.push(p);
            return;
        }
        // The input polyline (arcs linearised), Z along the length.
        let pts = m.points(self.chord);
        let xy_total: f64 = pts
            .windows(2)
            .map(|w| (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]))
            .sum();
        let mut at = 0.0;
        let mut prev = m.from;
        let len_in = (xy_total.powi(2) + (m.to[2] - m.from[2]).powi(2)).sqrt();
        let section_in = if m.e > 0.0 && len_in > 1e-9 {
            Some(m.e * self.filament_area / len_in)
        } else {
            None
        };
        let mut ends = Vec::new();
        for w in pts.windows(2) {
            at += (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]);
            let f = if xy_total > 0.0 { at / xy_total } else { 1.0 };
            let next = [w[1][0], w[1][1], m.from[2] + (m.to[2] - m.from[2]) * f];
            ends.clear();
            if dist3(prev, next) > 1e-9 {
                self.subdivide(prev, next, &mut ends);
            } else {
                ends.push((self.point(next), 1.0));
            }
            let mut u_prev = 0.0;
            let mut p_prev = self.point(prev);
            for &(p, u) in &ends {
                let um = (u_prev + u) / 2.0;
                let mid_in = [0, 1, 2].map(|i| prev[i] + (next[i] - prev[i]) * um);
                let v = self.vars(mid_in);
                let e = match section_in {
                    Some(c) => {
                        let c2 = match &self.section {
                            Some(x) => x.eval(&[c, v[0], v[1], v[2], v[3], v[4]]),
                            None => c,
                        };
                        if !(c2.is_finite() && c2 >= 0.0) {
                            self.note(|| {
                                format!(
                                    "--cross-section gives {c2} mm2 at x {:.3} y {:.3} z {:.3}; it must be a number >= 0",
                                    mid_in[0], mid_in[1], mid_in[2]
                                )
                            });
                        }
                        c2.max(0.0) * dist3(p_prev, p) / self.filament_area
                    }
                    // A travel or retraction: its E on its last piece.
                    None => 0.0,
                };
                let feed = match &self.speed {
                    Some(x) => {
                        let s = x.eval(&[m.feed / 60.0, v[0], v[1], v[2], v[3], v[4]]);
                        if !(s.is_finite() && s > 0.0) {
                            self.note(|| {
                                format!(
                                    "--speed gives {s} mm/s at x {:.3} y {:.3} z {:.3}; it must be a number > 0",
                                    mid_in[0], mid_in[1], mid_in[2]
                                )
                            });
                        }
                        MmPerMin(60.0 * s.clamp(0.1, 1000.0))
                    }
                    None => MmPerMin(m.feed),
                };
                if p.iter().any(|c| !c.is_finite()) {
                    self.note(|| {
                        format!(
                            "the position expressions give no number at x {:.3} y {:.3} z {:.3}",
                            mid_in[0], mid_in[1], mid_in[2]
                        )
                    });
                }
                out.push(Piece { to: p, e, feed });
                u_prev = u;
                p_prev = p;
            }
            prev = next;
        }
        if section_in.is_none() && m.e != 0.0 {
            // A travel or retraction in the helix: its E on its last piece.
            if let Some(last) = out.last_mut() {
                last.e += m.e;
            }
        }
        if pts.len() < 2 || out.is_empty() {
            // A move with no XY: Z or E only.
            let p = self.point(m.to);
            out.push(Piece {
                to: p,
                e: m.e,
                feed: MmPerMin(m.feed),
            });
        }
        self.pieces += out.len() as u64;
        if self.pieces > MAX_PIECES {
            let chord = self.chord;
            self.note(|| {
                format!("the deformation needs more than {MAX_PIECES} moves at --chord {chord} mm; give a larger --chord")
            });
        }
        if m.line == self.helix.last_line {
            self.top_out = out.last().map(|p| p.to[2]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::helix::{find, tests::vase};
    use crate::movemap::apply;
    use crate::writer::Cartesian;

    #[test]
    fn the_dish_maps_turns_outward_and_keeps_the_bead() {
        let text = vase(15.0, 0.2, 20);
        let h = find(text.as_bytes()).unwrap();
        let spec = Spec::preset("dish", &[]).unwrap();
        let fa = crate::layers::filament_area(1.75);
        let mut d = Deform::new(&spec, &h, fa).unwrap();
        // A point 2 mm above the first turn: r + 2.1, z 0.6 above the base.
        let p = d.point([115.0, 100.0, 0.4 + 2.0]);
        assert!(
            (p[0] - 117.1).abs() < 1e-9 && (p[2] - (0.4 + 0.6)).abs() < 1e-9,
            "{p:?}"
        );
        let mut out = Vec::new();
        apply(text.as_bytes(), &mut d, &Cartesian, &mut out).unwrap();
        assert!(d.problem().is_none());
        // E per mm of the output helix = E per mm as sliced (0.035).
        let mut e = 0.0;
        let mut len = 0.0;
        crate::helix::moves(&out, |m, _| {
            if m.is_extrusion() && m.from[2] > 0.45 {
                e += m.e;
                len += dist3(m.from, m.to);
            }
        });
        assert!((e / len - 0.035).abs() < 0.035 * 0.005, "{}", e / len);
    }

    #[test]
    fn presets_check_their_parameters() {
        assert!(Spec::preset("dihs", &[])
            .unwrap_err()
            .to_string()
            .contains("dish"));
        let e = Spec::preset("dish", &[("kk".into(), 1.0)])
            .unwrap_err()
            .to_string();
        assert!(e.contains("k, s"), "{e}");
        let text = vase(15.0, 0.2, 20);
        let h = find(text.as_bytes()).unwrap();
        let s = Spec::preset("sphere", &[("R".into(), 10.0)]).unwrap();
        assert!(Deform::new(&s, &h, 2.4).is_err());
        let s = Spec::expressions(Frame::Cylindrical, "r + zz; theta; z", &[]).unwrap();
        let e = Deform::new(&s, &h, 2.4).err().unwrap().to_string();
        assert!(e.contains("column 5") && e.contains("`zz`"), "{e}");
    }
}
