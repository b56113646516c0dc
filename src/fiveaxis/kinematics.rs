//! Kinematics of a table-tilting five-axis printer: the nozzle stays vertical, the bed turns
//! about its own vertical axis (C) and tilts about a horizontal one (B about Y, or A about X).
//!
//! Input: a [`Machine`] (layout, axis letters, signs, zero offsets, pivots, limits) and a
//! workpiece pose: a point on the part and the direction material is laid along (the layer
//! normal, pointing from the part to the nozzle), both in the workpiece frame (the bed's frame
//! with both rotary axes at zero). Output: [`Joints`] (X, Y, Z, tilt, turn), and back.
//!
//! Model: a workpiece point p is carried by the turn about the vertical axis through
//! `pivot_turn`, then by the tilt about the horizontal axis through `pivot_tilt`:
//! `q = Pt + R_tilt(-tilt) (Pc + R_z(-turn) (p - Pc) - Pt)`; the nozzle tip goes to q. The
//! direction n = (i, j, k) is brought to +Z: tilt = acos(k), turn = atan2(j, i) (B/C; for A/C
//! turn = atan2(-i, j)... see [`Machine::inverse`]), the paper's B = arccos k, C = atan2(j, i).
//!
//! Invariants: `forward(inverse(p, n)) = (p, n)` to 1e-9; near tilt 0 the turn is kept from
//! the previous pose (it is free there); turns are unwrapped to the previous pose's (no
//! 360 deg spins), and of the two solutions (tilt, turn) and (-tilt, turn + 180) the nearer
//! one within the limits is taken.

use serde::Deserialize;

use crate::error::Error;

pub type V3 = [f64; 3];

/// Which horizontal axis the bed tilts about.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Layout {
    /// Tilt B about Y, turn C about Z (the paper's machine).
    Bc,
    /// Tilt A about X, turn C about Z.
    Ac,
}

/// G-code dialect of the joint file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Flavour {
    Reprapfirmware,
    Marlin,
    Klipper,
}

/// A table-tilting machine, as a YAML file describes it (every key required).
#[derive(Debug, Clone, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct Machine {
    pub name: String,
    pub layout: Layout,
    pub flavour: Flavour,
    /// Letters of the tilt and turn axes in the G-code (e.g. B and C).
    pub tilt_letter: char,
    pub turn_letter: char,
    /// +1 or -1: the direction the firmware turns for a positive value.
    pub tilt_sign: f64,
    pub turn_sign: f64,
    /// Joint value (deg) written when the bed is level / unturned.
    pub tilt_zero: f64,
    pub turn_zero: f64,
    /// A point on the tilt axis, bed frame (mm).
    pub pivot_tilt: V3,
    /// Where the turn axis passes, bed frame at tilt 0 (mm; it is vertical there).
    pub pivot_turn: [f64; 2],
    /// Joint limits: X, Y, Z in mm, tilt and turn in degrees, as [min, max].
    pub limit_x: [f64; 2],
    pub limit_y: [f64; 2],
    pub limit_z: [f64; 2],
    pub limit_tilt: [f64; 2],
    pub limit_turn: [f64; 2],
    /// Fastest turn or tilt (deg/s).
    pub max_angular_speed: f64,
    /// The hot end as the collision check sees it: a disk of this radius (mm, the heater
    /// block and its fan duct) this high above the nozzle tip (mm). Optional.
    #[serde(default = "default_hotend_radius")]
    pub hotend_radius: f64,
    #[serde(default = "default_hotend_height")]
    pub hotend_height: f64,
}

fn default_hotend_radius() -> f64 {
    12.0
}

fn default_hotend_height() -> f64 {
    5.0
}

/// A pose in joint space: X, Y, Z (mm) and tilt, turn (radians, machine sense, before sign
/// and zero offset).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Joints {
    pub xyz: V3,
    pub tilt: f64,
    pub turn: f64,
}

/// The built-in machines: name and YAML.
pub const BUILT_INS: &[(&str, &str)] = &[("sfam", SFAM_YAML), ("ac-demo", AC_DEMO_YAML)];

/// The paper's B/C table-tilting printer, with the pivots where a 250 x 210 mm bed on a
/// trunnion would put them: the tilt axis 125 mm in X, at bed height, the turn axis at the bed's
/// centre. Measure yours and write your own file (`poa machines sfam` prints this one).
pub const SFAM_YAML: &str = "\
# The paper's layout: the bed tilts about Y (B) and turns about its own vertical axis (C).
name: sfam
layout: bc            # bc: tilt B about Y, turn C about Z; ac: tilt A about X
flavour: reprapfirmware   # reprapfirmware | marlin | klipper
tilt_letter: B
turn_letter: C
tilt_sign: 1          # +1 or -1: which way the firmware tilts for a positive B
turn_sign: 1
tilt_zero: 0          # B written when the bed is level (deg)
turn_zero: 0
pivot_tilt: [125.0, 105.0, 0.0]   # a point on the tilt axis (mm, bed frame)
pivot_turn: [125.0, 105.0]        # where the turn axis passes (mm, at B = 0)
limit_x: [0.0, 250.0]
limit_y: [0.0, 210.0]
limit_z: [0.0, 200.0]
limit_tilt: [-100.0, 100.0]       # degrees
limit_turn: [-36000.0, 36000.0]   # degrees: C turns without end stops, unwrapped
max_angular_speed: 180.0          # deg/s
hotend_radius: 12.0               # the hot end as a disk (mm) for the collision check ...
hotend_height: 5.0                # ... this high above the nozzle tip (mm)
";

/// An A/C machine (tilt about X), to show the second layout.
pub const AC_DEMO_YAML: &str = "\
# An A/C layout: the bed tilts about X (A) and turns about its own vertical axis (C).
name: ac-demo
layout: ac
flavour: klipper
tilt_letter: A
turn_letter: C
tilt_sign: 1
turn_sign: 1
tilt_zero: 0
turn_zero: 0
pivot_tilt: [110.0, 110.0, 0.0]
pivot_turn: [110.0, 110.0]
limit_x: [0.0, 220.0]
limit_y: [0.0, 220.0]
limit_z: [0.0, 180.0]
limit_tilt: [-95.0, 95.0]
limit_turn: [-36000.0, 36000.0]
max_angular_speed: 120.0
";

fn rot_x(a: f64, v: V3) -> V3 {
    let (s, c) = a.sin_cos();
    [v[0], c * v[1] - s * v[2], s * v[1] + c * v[2]]
}

fn rot_y(a: f64, v: V3) -> V3 {
    let (s, c) = a.sin_cos();
    [c * v[0] + s * v[2], v[1], -s * v[0] + c * v[2]]
}

fn rot_z(a: f64, v: V3) -> V3 {
    let (s, c) = a.sin_cos();
    [c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]]
}

fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// Unit vector of `v` (`None` for a zero vector).
pub fn unit(v: V3) -> Option<V3> {
    let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    (l > 1e-12 && l.is_finite()).then(|| [v[0] / l, v[1] / l, v[2] / l])
}

/// Below this tilt (radians) the turn is free: the previous one is kept.
const SINGULAR: f64 = 1e-6;

impl Machine {
    /// Reads and checks a machine file; errors name the key and the value.
    pub fn from_yaml(text: &str) -> Result<Machine, Error> {
        let m: Machine =
            serde_yaml::from_str(text).map_err(|e| Error::Invalid(format!("machine file: {e}")))?;
        m.validate()?;
        Ok(m)
    }

    /// A built-in machine by name, or a YAML file.
    pub fn load(name_or_path: &str) -> Result<Machine, Error> {
        if let Some((_, yaml)) = BUILT_INS.iter().find(|(n, _)| *n == name_or_path) {
            return Machine::from_yaml(yaml);
        }
        let path = std::path::Path::new(name_or_path);
        let meta = std::fs::metadata(path).map_err(|e| {
            let names: Vec<&str> = BUILT_INS.iter().map(|(n, _)| *n).collect();
            Error::Invalid(format!(
                "--machine {name_or_path}: {e} (built-in machines: {})",
                names.join(", ")
            ))
        })?;
        if !meta.is_file() || meta.len() > 1024 * 1024 {
            return Err(Error::Invalid(format!(
                "--machine {name_or_path}: not a YAML file of at most 1 MiB"
            )));
        }
        let text = std::fs::read_to_string(path)
            .map_err(|e| Error::Invalid(format!("--machine {name_or_path}: {e}")))?;
        Machine::from_yaml(&text).map_err(|e| match e {
            Error::Invalid(m) => Error::Invalid(format!("{name_or_path}: {m}")),
            other => other,
        })
    }

    fn validate(&self) -> Result<(), Error> {
        let bad = |m: String| Err(Error::Invalid(format!("machine file: {m}")));
        for (key, c) in [
            ("tilt_letter", self.tilt_letter),
            ("turn_letter", self.turn_letter),
        ] {
            if !"ABCUVW".contains(c) {
                return bad(format!(
                    "{key}: `{c}` is not a rotary axis letter (A, B, C, U, V, W)"
                ));
            }
        }
        if self.tilt_letter == self.turn_letter {
            return bad(format!(
                "tilt_letter and turn_letter are both `{}`",
                self.tilt_letter
            ));
        }
        for (key, s) in [("tilt_sign", self.tilt_sign), ("turn_sign", self.turn_sign)] {
            if s != 1.0 && s != -1.0 {
                return bad(format!("{key}: {s} (must be 1 or -1)"));
            }
        }
        let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
        if !finite(&self.pivot_tilt) || !finite(&self.pivot_turn) {
            return bad("pivot_tilt and pivot_turn must be numbers".into());
        }
        for (key, l) in [
            ("limit_x", self.limit_x),
            ("limit_y", self.limit_y),
            ("limit_z", self.limit_z),
            ("limit_tilt", self.limit_tilt),
            ("limit_turn", self.limit_turn),
        ] {
            if !finite(&l) || l[1] <= l[0] {
                return bad(format!(
                    "{key}: [{}, {}] (give [min, max] with min < max)",
                    l[0], l[1]
                ));
            }
        }
        if !(self.tilt_zero.is_finite() && self.turn_zero.is_finite()) {
            return bad("tilt_zero and turn_zero must be numbers".into());
        }
        for (key, v) in [
            ("hotend_radius", self.hotend_radius),
            ("hotend_height", self.hotend_height),
        ] {
            if !(v.is_finite() && (0.0..=200.0).contains(&v)) {
                return bad(format!("{key}: {v} (mm, 0 to 200)"));
            }
        }
        if !(self.max_angular_speed.is_finite() && self.max_angular_speed > 0.0) {
            return bad(format!(
                "max_angular_speed: {} (deg/s, more than 0)",
                self.max_angular_speed
            ));
        }
        Ok(())
    }

    fn tilt_rot(&self, a: f64, v: V3) -> V3 {
        match self.layout {
            Layout::Bc => rot_y(a, v),
            Layout::Ac => rot_x(a, v),
        }
    }

    fn pivot_turn3(&self) -> V3 {
        [self.pivot_turn[0], self.pivot_turn[1], 0.0]
    }

    /// Where workpiece point `p` is when the bed is at `tilt`, `turn` (radians).
    fn carry(&self, p: V3, tilt: f64, turn: f64) -> V3 {
        let pc = self.pivot_turn3();
        let turned = add(pc, rot_z(-turn, sub(p, pc)));
        add(
            self.pivot_tilt,
            self.tilt_rot(-tilt, sub(turned, self.pivot_tilt)),
        )
    }

    /// The bed angles that bring direction `n` to +Z, the nearer of the two solutions to
    /// `prev` (and within the limits when one is); `None` when neither is within the limits.
    fn angles(&self, n: V3, prev: Option<(f64, f64)>) -> Option<(f64, f64)> {
        // B/C: R_y(-tilt) R_z(-turn) n = +Z  <=>  n = (sin t cos c, sin t sin c, cos t).
        // A/C: R_x(-tilt) R_z(-turn) n = +Z  <=>  n = (sin t sin c, -sin t cos c, cos t).
        let tilt = n[2].clamp(-1.0, 1.0).acos();
        let turn0 = match self.layout {
            Layout::Bc => n[1].atan2(n[0]),
            Layout::Ac => n[0].atan2(-n[1]),
        };
        let (pt, pc) = prev.unwrap_or((0.0, 0.0));
        let turn0 = if tilt < SINGULAR { pc } else { turn0 };
        let unwrap = |c: f64| {
            let k = ((pc - c) / std::f64::consts::TAU).round();
            c + k * std::f64::consts::TAU
        };
        let lim = |l: [f64; 2]| [l[0].to_radians(), l[1].to_radians()];
        let (lt, lc) = (lim(self.limit_tilt), lim(self.limit_turn));
        let within = |t: f64, c: f64| {
            let t = self.tilt_sign * t + self.tilt_zero.to_radians();
            let c = self.turn_sign * c + self.turn_zero.to_radians();
            t >= lt[0] - 1e-9 && t <= lt[1] + 1e-9 && c >= lc[0] - 1e-9 && c <= lc[1] + 1e-9
        };
        let a = (tilt, unwrap(turn0));
        let b = (-tilt, unwrap(turn0 + std::f64::consts::PI));
        let cost = |s: (f64, f64)| (s.0 - pt).abs() + (s.1 - pc).abs();
        let mut options = [a, b];
        options.sort_by(|x, y| cost(*x).total_cmp(&cost(*y)));
        options.into_iter().find(|s| within(s.0, s.1))
    }

    /// Joints that put workpiece point `p` under the nozzle with direction `n` vertical.
    /// `prev` is the previous pose (turn kept at the singularity, unwrapped, nearer
    /// solution). Errors say which limit is crossed.
    pub fn inverse(&self, p: V3, n: V3, prev: Option<&Joints>) -> Result<Joints, Error> {
        let n = unit(n).ok_or_else(|| Error::Invalid("a tool direction of length 0".into()))?;
        let (tilt, turn) = self
            .angles(n, prev.map(|j| (j.tilt, j.turn)))
            .ok_or_else(|| {
                Error::Refused(format!(
                    "direction ({:.3}, {:.3}, {:.3}) needs a tilt of {:.1} deg, outside limit_tilt [{}, {}]",
                    n[0],
                    n[1],
                    n[2],
                    n[2].clamp(-1.0, 1.0).acos().to_degrees(),
                    self.limit_tilt[0],
                    self.limit_tilt[1]
                ))
            })?;
        let xyz = self.carry(p, tilt, turn);
        for (i, (axis, l)) in [
            ("X", self.limit_x),
            ("Y", self.limit_y),
            ("Z", self.limit_z),
        ]
        .into_iter()
        .enumerate()
        {
            if xyz[i] < l[0] - 1e-9 || xyz[i] > l[1] + 1e-9 {
                return Err(Error::Refused(format!(
                    "{axis} {:.3} is outside limit_{} [{}, {}]",
                    xyz[i],
                    axis.to_ascii_lowercase(),
                    l[0],
                    l[1]
                )));
            }
        }
        Ok(Joints { xyz, tilt, turn })
    }

    /// Clearance (mm) between the tilted bed's plane and the lowest point of the hot end's
    /// disk when the nozzle tip is on workpiece point `p` at `tilt` (negative: the bed would
    /// hit the hot end). The bed is the workpiece plane z = 0; tilting it by t brings it
    /// `r sin t` up at `r` from the nozzle while the disk sits `H cos t` further along the
    /// bed's normal.
    pub fn clearance(&self, p: V3, tilt: f64) -> f64 {
        p[2] + self.hotend_height * tilt.cos() - self.hotend_radius * tilt.sin().abs()
    }

    /// The workpiece point under the nozzle and the direction that is vertical, at `j`.
    pub fn forward(&self, j: &Joints) -> (V3, V3) {
        let pc = self.pivot_turn3();
        let turned = add(
            self.pivot_tilt,
            self.tilt_rot(j.tilt, sub(j.xyz, self.pivot_tilt)),
        );
        let p = add(pc, rot_z(j.turn, sub(turned, pc)));
        let n = rot_z(j.turn, self.tilt_rot(j.tilt, [0.0, 0.0, 1.0]));
        (p, n)
    }

    /// The rotary axes' values as written (degrees, with sign and zero offset).
    pub fn written(&self, j: &Joints) -> (f64, f64) {
        (
            self.tilt_sign * j.tilt.to_degrees() + self.tilt_zero,
            self.turn_sign * j.turn.to_degrees() + self.turn_zero,
        )
    }

    /// Joints from the values as written (inverse of [`Machine::written`]).
    pub fn from_written(&self, xyz: V3, tilt_deg: f64, turn_deg: f64) -> Joints {
        Joints {
            xyz,
            tilt: ((tilt_deg - self.tilt_zero) * self.tilt_sign).to_radians(),
            turn: ((turn_deg - self.turn_zero) * self.turn_sign).to_radians(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small deterministic generator (xorshift) for random poses.
    fn rng(seed: &mut u64) -> f64 {
        *seed ^= *seed << 13;
        *seed ^= *seed >> 7;
        *seed ^= *seed << 17;
        (*seed >> 11) as f64 / (1u64 << 53) as f64
    }

    #[test]
    fn forward_undoes_inverse_over_random_poses_on_both_layouts() {
        for (name, _) in BUILT_INS {
            let mut m = Machine::load(name).unwrap();
            // Wide travel: this test is about the transforms, not the limits.
            m.limit_x = [-1e4, 1e4];
            m.limit_y = [-1e4, 1e4];
            m.limit_z = [-1e4, 1e4];
            let mut seed = 0x9e37_79b9_7f4a_7c15u64;
            let mut prev: Option<Joints> = None;
            for _ in 0..10_000 {
                let p = [
                    100.0 + 40.0 * rng(&mut seed),
                    90.0 + 40.0 * rng(&mut seed),
                    5.0 + 30.0 * rng(&mut seed),
                ];
                // Directions in the upper hemisphere and a little below it.
                let th = 1.5 * rng(&mut seed);
                let ph = std::f64::consts::TAU * rng(&mut seed);
                let n = [th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()];
                let j = m.inverse(p, n, prev.as_ref()).unwrap();
                let (q, d) = m.forward(&j);
                for i in 0..3 {
                    assert!((q[i] - p[i]).abs() < 1e-9, "{name}: {p:?} -> {q:?}");
                    assert!((d[i] - n[i]).abs() < 1e-9, "{name}: {n:?} -> {d:?}");
                }
                // Written and read back, the same pose.
                let (t, c) = m.written(&j);
                let back = m.from_written(j.xyz, t, c);
                assert!((back.tilt - j.tilt).abs() < 1e-12 && (back.turn - j.turn).abs() < 1e-12);
                prev = Some(j);
            }
        }
    }

    #[test]
    fn the_turn_is_kept_at_the_singularity_and_never_spins_round() {
        let m = Machine::load("sfam").unwrap();
        let p = [125.0, 105.0, 10.0];
        let a = m
            .inverse(p, [0.5f64.sin(), 0.0, 0.5f64.cos()], None)
            .unwrap();
        // Straight up: tilt 0, the turn stays what it was.
        let up = m.inverse(p, [0.0, 0.0, 1.0], Some(&a)).unwrap();
        assert!(up.tilt.abs() < 1e-9 && (up.turn - a.turn).abs() < 1e-12);
        // Going round the part three times: the turn grows past 360 deg instead of jumping back.
        let mut prev = a;
        for k in 1..=1080 {
            let c = (k as f64).to_radians();
            let n = [0.5f64.sin() * c.cos(), 0.5f64.sin() * c.sin(), 0.5f64.cos()];
            let j = m.inverse(p, n, Some(&prev)).unwrap();
            assert!(
                (j.turn - prev.turn).abs() < 0.02,
                "jump at {k}: {} -> {}",
                prev.turn,
                j.turn
            );
            prev = j;
        }
        assert!(prev.turn.to_degrees() > 1079.0);
    }

    #[test]
    fn bad_machine_files_are_refused_naming_the_value() {
        let with = |from: &str, to: &str| SFAM_YAML.replace(from, to);
        let cases = [
            (with("name: sfam\n", ""), "name"),
            (
                with("limit_tilt: [-100.0, 100.0]", "limit_tilt: [0.0, 0.0]"),
                "limit_tilt: [0, 0]",
            ),
            (with("tilt_letter: B", "tilt_letter: Q"), "`Q`"),
            (with("tilt_sign: 1 ", "tilt_sign: 2 "), "tilt_sign: 2"),
            (with("layout: bc", "layout: xy"), "layout"),
            (format!("{SFAM_YAML}extra: 1\n"), "extra"),
            (
                with("hotend_radius: 12.0", "hotend_radius: -1"),
                "hotend_radius: -1",
            ),
        ];
        for (yaml, want) in cases {
            let e = Machine::from_yaml(&yaml).unwrap_err().to_string();
            assert!(e.contains(want), "{want}: {e}");
        }
        let m = Machine::load("sfam").unwrap();
        let e = m
            .inverse([125.0, 105.0, 10.0], [0.0, 0.0, -1.0], None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("limit_tilt"), "{e}");
    }
}
