//! A/B test plates: the original part and a translated copy, printed layer by layer.
//!
//! Input: the text of a single-part slice, its [`SlicerConfig`] and an offset. Output: G-code
//! that prints, in every layer, the original layer's lines unchanged, then a clean travel
//! (retract, lift, move, lower, unretract) to the copy, the copy's lines with X/Y shifted by
//! the offset, and a clean travel back before the rest of the original layer (the slicer's
//! layer change and, after the last layer, its end G-code). The copy is labelled as its own
//! object in the input's labelling style (PrusaSlicer comments, M486, Klipper
//! EXCLUDE_OBJECT), so that [`crate::emit::process`] can rewrite it alone and the printer can
//! cancel either.
//!
//! Invariants: refuses, without output, a copy that would leave the bed or come within the
//! safety gap of the original's material (every extrusion, skirt and priming line included),
//! and files whose coordinates the shift cannot follow (relative XY moves, G92 on X/Y).

use std::fmt::Write as _;

use crate::error::Error;
use crate::gcode::{parse_line, split_lines, strip_terminator, Command};
use crate::layers::{LayerKind, LayerReader, ReaderOptions, SlicerConfig};
use crate::machine::{Action, Machine};
use crate::pass::Pass;
use crate::writer::{fmt_mm as fmt, MmPerMin, TravelStyle, Writer};

/// How to lay out the copy.
#[derive(Debug, Clone)]
pub struct AbOptions {
    /// Shift of the copy (mm).
    pub offset: [f64; 2],
    /// Least distance between the copy's material and the original's (mm).
    pub gap: f64,
    /// Bed rectangle `[x0, y0, x1, y1]` overriding the file's bed shape.
    pub bed: Option<[f64; 4]>,
}

/// What was built.
#[derive(Debug, Clone)]
pub struct AbPlate {
    pub text: Vec<u8>,
    /// The copy's object name, as the layer reader will report it (the first object's copy,
    /// when the slice has several).
    pub copy_name: String,
    /// Every copied object's name, as the layer reader will report it.
    pub copy_names: Vec<String>,
    pub layers: usize,
    /// Filament (mm) and print time (s) the copy and its travels add.
    pub added_filament_mm: f64,
    pub added_time_s: f64,
    /// Where in `text` each layer's copy ends and the time it took, for progress lines.
    pub added: Vec<crate::progress::Added>,
}

/// Axis-aligned box of material (mm).
#[derive(Debug, Clone, Copy)]
struct Bounds {
    min: [f64; 2],
    max: [f64; 2],
}

impl Bounds {
    fn empty() -> Bounds {
        Bounds {
            min: [f64::INFINITY; 2],
            max: [f64::NEG_INFINITY; 2],
        }
    }

    fn add(&mut self, p: [f64; 2], r: f64) {
        for ((lo, hi), v) in self.min.iter_mut().zip(self.max.iter_mut()).zip(p) {
            *lo = lo.min(v - r);
            *hi = hi.max(v + r);
        }
    }

    fn is_empty(&self) -> bool {
        self.min[0] > self.max[0]
    }

    fn shifted(&self, d: [f64; 2]) -> Bounds {
        Bounds {
            min: [self.min[0] + d[0], self.min[1] + d[1]],
            max: [self.max[0] + d[0], self.max[1] + d[1]],
        }
    }

    /// Distance between two boxes (0 when they overlap).
    fn distance(&self, o: &Bounds) -> f64 {
        let dx = (o.min[0] - self.max[0])
            .max(self.min[0] - o.max[0])
            .max(0.0);
        let dy = (o.min[1] - self.max[1])
            .max(self.min[1] - o.max[1])
            .max(0.0);
        (dx * dx + dy * dy).sqrt()
    }
}

/// The bed's outline from `bed_shape = 0x0,250x0,250x210,0x210`.
fn bed_polygon(config: &SlicerConfig) -> Option<Vec<[f64; 2]>> {
    let v = config.get("bed_shape")?;
    let pts: Option<Vec<[f64; 2]>> = v
        .split(',')
        .map(|p| {
            let (x, y) = p.trim().split_once('x')?;
            Some([x.trim().parse().ok()?, y.trim().parse().ok()?])
        })
        .collect();
    pts.filter(|p| p.len() >= 3)
}

fn inside_polygon(poly: &[[f64; 2]], p: [f64; 2]) -> bool {
    // A point on the edge counts as inside: a part may touch the bed's edge.
    let mut inside = false;
    let n = poly.len();
    for i in 0..n {
        let (a, b) = (poly[i], poly[(i + 1) % n]);
        let cross = (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]);
        let on_segment = cross.abs() < 1e-9
            && p[0] >= a[0].min(b[0]) - 1e-9
            && p[0] <= a[0].max(b[0]) + 1e-9
            && p[1] >= a[1].min(b[1]) - 1e-9
            && p[1] <= a[1].max(b[1]) + 1e-9;
        if on_segment {
            return true;
        }
        if (a[1] > p[1]) != (b[1] > p[1]) {
            let x = a[0] + (p[1] - a[1]) * (b[0] - a[0]) / (b[1] - a[1]);
            if p[0] < x {
                inside = !inside;
            }
        }
    }
    inside
}

/// How the input labels objects.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Labels {
    /// `; printing object NAME id:N copy K` / `; stop printing object ...`.
    Comments,
    /// `M486 S<id>` (Marlin, Prusa firmware); copies take ids from `first_free` on.
    M486 {
        first_free: i64,
    },
    /// `EXCLUDE_OBJECT_START NAME=...` (Klipper).
    Klipper,
    /// `;MESH:name` ... `;MESH:NONMESH` (Cura).
    Cura,
    None,
}

fn detect_labels(text: &[u8]) -> Labels {
    let mut max_id: Option<i64> = None;
    let mut comments = false;
    let mut klipper = false;
    let mut cura = false;
    for raw in split_lines(text) {
        let t = strip_terminator(raw).trim_ascii();
        if t.starts_with(b";MESH:") && t != b";MESH:NONMESH" {
            cura = true;
        } else if t.starts_with(b"; printing object ") {
            comments = true;
        } else if t.starts_with(b"EXCLUDE_OBJECT_START") {
            klipper = true;
        } else if t.starts_with(b"M486") {
            if let Some(s) = parse_line(t).get(b'S').filter(|s| *s >= 0.0) {
                max_id = Some(max_id.map_or(s as i64, |m: i64| m.max(s as i64)));
            }
        }
    }
    if comments {
        Labels::Comments
    } else if let Some(m) = max_id {
        Labels::M486 { first_free: m + 1 }
    } else if klipper {
        Labels::Klipper
    } else if cura {
        Labels::Cura
    } else {
        Labels::None
    }
}

fn refused(why: impl Into<String>) -> Error {
    Error::Refused(why.into())
}

/// Builds the A/B plate from the text of a slice: checks that the copy fits, then runs
/// [`AbPass`] over the layers.
pub fn build(text: &[u8], config: &SlicerConfig, opts: &AbOptions) -> Result<AbPlate, Error> {
    let d = opts.offset;
    if !(d[0].is_finite() && d[1].is_finite()) || (d[0] == 0.0 && d[1] == 0.0) {
        return Err(refused("the offset must be a non-zero DX,DY in mm"));
    }
    let reader = LayerReader::new(
        text,
        ReaderOptions {
            keep_raw: true,
            config: config.clone(),
        },
    );
    let mut layers = Vec::new();
    for l in reader {
        layers.push(l.map_err(|e| refused(format!("cannot read the file: {e}")))?);
    }
    check_fits(&layers, config, opts)?;
    if let Some(line) =
        split_lines(text).position(|raw| parse_line(strip_terminator(raw)).is_code(b'G', 20.0))
    {
        return Err(refused(format!(
            "line {} switches to inches (G20); poa ab needs a file in millimetres",
            line + 1
        )));
    }
    let labels = detect_labels(text);
    let copy_names = copy_object_names(&layers, labels);
    let mut pass = AbPass::new(config, d, labels, copy_names[0].clone());
    let mut out: Vec<u8> = Vec::with_capacity(text.len() * 2);
    for l in layers {
        let found = crate::geometry::Detected::plain(l);
        let at = out.len() as u64;
        match pass.layer(&found)? {
            Some(bytes) => out.extend_from_slice(&bytes),
            None => out.extend_from_slice(&found.layer.raw),
        }
        // The pass counts progress offsets from its layer's start.
        for a in &mut pass.added[pass.placed..] {
            a.offset += at;
        }
        pass.placed = pass.added.len();
    }
    Ok(AbPlate {
        text: out,
        copy_name: copy_names[0].clone(),
        copy_names,
        layers: pass.count,
        added_filament_mm: pass.added_filament,
        added_time_s: pass.added_time,
        added: pass.added,
    })
}

/// Refuses a copy that would leave the bed or come within the gap of the original's
/// material.
fn check_fits(
    layers: &[crate::layers::Layer],
    config: &SlicerConfig,
    opts: &AbOptions,
) -> Result<(), Error> {
    let mut copied = Bounds::empty();
    for l in layers.iter().filter(|l| l.kind == LayerKind::Layer) {
        for p in &l.paths {
            for q in &p.points {
                copied.add(*q, p.width / 2.0);
            }
        }
    }
    if copied.is_empty() {
        return Err(refused("the file prints nothing to copy"));
    }
    let copy = copied.shifted(opts.offset);
    // Clearance from every strand of the original (part, skirt, priming line), each by its
    // own box, so that a priming line along the bed's edge does not block the whole bed.
    let gap = layers
        .iter()
        .flat_map(|l| l.paths.iter())
        .map(|p| {
            let mut b = Bounds::empty();
            for q in &p.points {
                b.add(*q, p.width / 2.0);
            }
            if b.is_empty() {
                f64::INFINITY
            } else {
                copy.distance(&b)
            }
        })
        .fold(f64::INFINITY, f64::min);
    if gap < opts.gap {
        return Err(refused(format!(
            "the copy would come within {gap:.1} mm of the original's material (at least {:.1} mm needed); choose a larger --offset",
            opts.gap
        )));
    }
    let bed = match (opts.bed, bed_polygon(config)) {
        (Some(b), _) => vec![[b[0], b[1]], [b[2], b[1]], [b[2], b[3]], [b[0], b[3]]],
        (None, Some(p)) => p,
        (None, None) => {
            return Err(refused(
                "the file does not state its bed shape; pass --bed X0,Y0,X1,Y1",
            ))
        }
    };
    let corners = [
        copy.min,
        [copy.max[0], copy.min[1]],
        copy.max,
        [copy.min[0], copy.max[1]],
    ];
    if let Some(c) = corners.iter().find(|c| !inside_polygon(&bed, **c)) {
        return Err(refused(format!(
            "the copy would leave the bed (its material would reach X{:.1} Y{:.1}); choose another --offset",
            c[0], c[1]
        )));
    }
    Ok(())
}

/// The A/B copy as a per-layer pass: after the original's last extrusion in each layer, a
/// junction travel, the layer's lines shifted and relabelled, and a junction back.
pub struct AbPass {
    d: [f64; 2],
    labels: Labels,
    copy_name: String,
    motion: Junction,
    /// The original's label open where the current layer starts (a slicer may open it in
    /// the layer before).
    open: Option<Vec<u8>>,
    /// Motion limits in force as the file goes (it changes accelerations per feature).
    limits: crate::estimate::Estimator,
    count: usize,
    added_filament: f64,
    added_time: f64,
    /// Per copied layer, where its copy ends (from the layer's start until placed) and the
    /// time it took.
    added: Vec<crate::progress::Added>,
    placed: usize,
}

impl AbPass {
    fn new(config: &SlicerConfig, d: [f64; 2], labels: Labels, copy_name: String) -> AbPass {
        AbPass {
            d,
            labels,
            copy_name,
            motion: Junction::from_config(config),
            open: None,
            limits: crate::estimate::Estimator::new(crate::estimate::Limits::from_config(config)),
            count: 0,
            added_filament: 0.0,
            added_time: 0.0,
            added: Vec::new(),
            placed: 0,
        }
    }

    /// Passes a layer through unchanged, following its labels and limits.
    fn pass_through(&mut self, l: &crate::layers::Layer) {
        self.limits.track_limits(&l.raw);
        for raw in split_lines(&l.raw) {
            track_label(&mut self.open, raw, self.labels);
        }
    }
}

impl Pass for AbPass {
    /// Long by design: the copy of one layer in print order (original, junction, shifted copy with its labels, junction back); the label state it threads through would otherwise be passed around.
    fn layer(&mut self, found: &crate::geometry::Detected) -> Result<Option<Vec<u8>>, Error> {
        let l = &found.layer;
        let (d, labels) = (self.d, self.labels);
        let lines: Vec<&[u8]> = split_lines(&l.raw).collect();
        let start = match (l.kind, l.start.as_deref()) {
            (LayerKind::Layer, Some(s)) => s,
            _ => {
                self.pass_through(l);
                if labels == Labels::Klipper {
                    let mut out = l.raw.clone();
                    define_klipper_copies(&l.raw, d, &mut out);
                    return Ok(Some(out));
                }
                return Ok(None);
            }
        };
        // The copy is the layer's lines up to its last extrusion: what follows is the next
        // layer's preparation, or the end G-code.
        let mut machine = start.clone();
        let mut cut = 0;
        let mut at_cut = machine.clone();
        for (i, raw) in lines.iter().enumerate() {
            let parsed = parse_line(strip_terminator(raw));
            check_shiftable(&parsed, &machine, l.first_line + i as u64)?;
            if let Action::Move(m) = machine.step(&parsed, l.first_line + i as u64) {
                if m.is_extrusion() {
                    cut = i + 1;
                    at_cut = machine.clone();
                }
            }
        }
        if cut == 0 {
            self.pass_through(l);
            return Ok(None);
        }
        self.count += 1;
        let open_at_start = self.open.clone();
        let mut out: Vec<u8> = Vec::with_capacity(l.raw.len() * 2 + 512);
        for raw in &lines[..cut] {
            out.extend_from_slice(raw);
            track_label(&mut self.open, raw, labels);
        }
        let nl = if l.raw.windows(2).any(|w| w == b"\r\n") {
            "\r\n"
        } else {
            "\n"
        };
        let open_at_cut = self.open.clone();
        let copy_from = out.len();
        // Travels belong to no object: a cancelled object's moves are skipped by firmware.
        if let Some(o) = &open_at_cut {
            out.extend_from_slice(stop_label(o, labels, nl).as_bytes());
        }
        self.motion.travel(&mut out, &at_cut, start, d, nl);
        let mut copy_open = open_at_start.clone();
        if let Some(o) = &open_at_start {
            out.extend_from_slice(&copy_line(o, d, labels).unwrap_or_default());
            out.extend_from_slice(nl.as_bytes());
        }
        if labels == Labels::None {
            let label = format!("; printing object {}", self.copy_name);
            out.extend_from_slice(label.as_bytes());
            out.extend_from_slice(nl.as_bytes());
            copy_open = Some(label.into_bytes());
        }
        for raw in &lines[..cut] {
            if let Some(line) = copy_line(raw, d, labels) {
                out.extend_from_slice(&line);
            }
            track_label(&mut copy_open, raw, labels);
        }
        if let Some(o) = &copy_open {
            let renamed = copy_line(o, d, labels).unwrap_or_else(|| o.clone());
            out.extend_from_slice(stop_label(&renamed, labels, nl).as_bytes());
        }
        let mut shifted_end = at_cut.clone();
        shifted_end.shift_xy(d);
        self.motion
            .travel(&mut out, &shifted_end, &at_cut, [0.0, 0.0], nl);
        if let Some(o) = &open_at_cut {
            out.extend_from_slice(o);
            out.extend_from_slice(nl.as_bytes());
        }
        // What the copy costs: its lines and both travels, from where the original stopped.
        let (t, f) = crate::estimate::run_text(&self.limits, &at_cut, &out[copy_from..]);
        self.added_filament += f;
        self.added_time += t;
        self.added.push(crate::progress::Added {
            offset: out.len() as u64,
            seconds: t,
        });
        self.limits.track_limits(&l.raw);
        for raw in &lines[cut..] {
            out.extend_from_slice(raw);
            track_label(&mut self.open, raw, labels);
        }
        Ok(Some(out))
    }
}

/// Follows object labels: `open` is the start line of the object being printed, if any.
fn track_label(open: &mut Option<Vec<u8>>, raw: &[u8], labels: Labels) {
    let t = strip_terminator(raw).trim_ascii();
    let (starts, stops) = match labels {
        Labels::Comments | Labels::None => (
            t.starts_with(b"; printing object "),
            t.starts_with(b"; stop printing object "),
        ),
        Labels::M486 { .. } if t.starts_with(b"M486") => match parse_line(t).get(b'S') {
            Some(s) if s >= 0.0 => (true, false),
            Some(_) => (false, true),
            None => (false, false),
        },
        Labels::Klipper => (
            t.starts_with(b"EXCLUDE_OBJECT_START"),
            t.starts_with(b"EXCLUDE_OBJECT_END"),
        ),
        Labels::Cura if t.starts_with(b";MESH:") => {
            let none = t == b";MESH:NONMESH";
            (!none, none)
        }
        _ => (false, false),
    };
    if starts {
        *open = Some(t.to_vec());
    } else if stops {
        *open = None;
    }
}

/// The line that closes the object `start` opened.
fn stop_label(start: &[u8], labels: Labels, nl: &str) -> String {
    let s = String::from_utf8_lossy(start.trim_ascii());
    match labels {
        Labels::M486 { .. } => format!("M486 S-1{nl}"),
        Labels::Cura => format!(";MESH:NONMESH{nl}"),
        Labels::Klipper => format!(
            "EXCLUDE_OBJECT_END{}{nl}",
            s.strip_prefix("EXCLUDE_OBJECT_START").unwrap_or("")
        ),
        _ => format!(
            "; stop printing object {}{nl}",
            s.strip_prefix("; printing object ").unwrap_or(&s)
        ),
    }
}

/// The names the copy's labels give its objects (as the layer reader reports them), one per
/// labelled object of the slice; at least one.
fn copy_object_names(layers: &[crate::layers::Layer], labels: Labels) -> Vec<String> {
    let originals: Vec<String> = layers
        .iter()
        .rev()
        .find_map(|l| l.objects.clone())
        .unwrap_or_default();
    let names: Vec<String> = match labels {
        Labels::Comments => originals.iter().map(|o| copy_comment_name(o)).collect(),
        Labels::M486 { first_free } => originals
            .iter()
            .filter_map(|o| {
                let id: i64 = o
                    .rsplit_once("id ")?
                    .1
                    .trim_end_matches(')')
                    .trim()
                    .parse()
                    .ok()?;
                Some(match o.split_once(" (id ") {
                    Some((name, _)) => format!("{name} (id {})", first_free + id),
                    None => format!("id {}", first_free + id),
                })
            })
            .collect(),
        Labels::Klipper | Labels::Cura => {
            originals.iter().map(|o| format!("{o}_poa_copy")).collect()
        }
        Labels::None => Vec::new(),
    };
    if names.is_empty() {
        vec!["poa_copy id:1 copy 0".into()]
    } else {
        names
    }
}

/// `part.stl id:0 copy 0` becomes `part.stl id:0 copy 1` (PrusaSlicer names a second instance
/// of one object so).
fn copy_comment_name(name: &str) -> String {
    match name.rsplit_once(" copy ") {
        Some((head, n)) => match n.trim().parse::<i64>() {
            Ok(k) => format!("{head} copy {}", k + 1),
            Err(_) => format!("{name} (poa copy)"),
        },
        None => format!("{name} (poa copy)"),
    }
}

/// Refuses what a shift of X and Y cannot follow.
fn check_shiftable(p: &crate::gcode::Parsed<'_>, m: &Machine, line: u64) -> Result<(), Error> {
    let Command::Code {
        letter: b'G',
        number,
    } = p.command
    else {
        return Ok(());
    };
    if (0.0..=3.0).contains(&number) && m.xyz_relative() && (p.has(b'X') || p.has(b'Y')) {
        return Err(refused(format!(
            "line {line} moves X/Y in relative mode (G91); poa ab needs absolute coordinates"
        )));
    }
    if number == 20.0 {
        return Err(refused(format!(
            "line {line} switches to inches (G20); poa ab needs a file in millimetres"
        )));
    }
    if number == 92.0 && (p.has(b'X') || p.has(b'Y')) {
        return Err(refused(format!(
            "line {line} sets the X/Y position (G92); poa ab cannot shift such a file"
        )));
    }
    Ok(())
}

/// A line of the copy: X/Y shifted on moves, labels renamed, layer markers and progress
/// lines left out (the copy prints inside the original's layer). `None` drops the line.
fn copy_line(raw: &[u8], d: [f64; 2], labels: Labels) -> Option<Vec<u8>> {
    let content = strip_terminator(raw);
    let t = content.trim_ascii();
    const DROP: [&[u8]; 8] = [
        b";LAYER_CHANGE",
        b";Z:",
        b";LAYER:",
        b";LAYER_COUNT",
        b";AFTER_LAYER_CHANGE",
        b";BEFORE_LAYER_CHANGE",
        b"M73",
        b"M117",
    ];
    if DROP.iter().any(|p| t.starts_with(p)) {
        return None;
    }
    let ending = &raw[content.len()..];
    let mut out: Vec<u8> = match labels {
        Labels::Comments
            if t.starts_with(b"; printing object ")
                || t.starts_with(b"; stop printing object ") =>
        {
            let s = String::from_utf8_lossy(t);
            let (head, name) = if let Some(n) = s.strip_prefix("; printing object ") {
                ("; printing object ", n)
            } else {
                (
                    "; stop printing object ",
                    &s["; stop printing object ".len()..],
                )
            };
            format!("{head}{}", copy_comment_name(name.trim())).into_bytes()
        }
        Labels::M486 { first_free } if t.starts_with(b"M486") => {
            let p = parse_line(t);
            match p.get(b'S') {
                Some(s) if s >= 0.0 => format!("M486 S{}", first_free + s as i64).into_bytes(),
                _ => content.to_vec(),
            }
        }
        Labels::Klipper
            if t.starts_with(b"EXCLUDE_OBJECT_START") || t.starts_with(b"EXCLUDE_OBJECT_END") =>
        {
            rename_klipper(content)
        }
        Labels::Cura if t.starts_with(b";MESH:") && t != b";MESH:NONMESH" => {
            let mut line = t.to_vec();
            line.extend_from_slice(b"_poa_copy");
            line
        }
        _ => shift_line(content, d),
    };
    out.extend_from_slice(ending);
    Some(out)
}

fn rename_klipper(content: &[u8]) -> Vec<u8> {
    let s = String::from_utf8_lossy(content);
    let mut out = String::new();
    for (i, part) in s.split(' ').enumerate() {
        if i > 0 {
            out.push(' ');
        }
        match part.strip_prefix("NAME=") {
            Some(n) => {
                let n = n.trim_matches('"');
                let _ = write!(out, "NAME={n}_poa_copy");
            }
            None => out.push_str(part),
        }
    }
    out.into_bytes()
}

/// After Klipper's `EXCLUDE_OBJECT_DEFINE` lines, the copy's definitions (shifted).
fn define_klipper_copies(raw: &[u8], d: [f64; 2], out: &mut Vec<u8>) {
    for line in split_lines(raw) {
        let content = strip_terminator(line);
        if !content.starts_with(b"EXCLUDE_OBJECT_DEFINE") {
            continue;
        }
        let s = String::from_utf8_lossy(content);
        let mut def = String::new();
        for (i, part) in s.split(' ').enumerate() {
            if i > 0 {
                def.push(' ');
            }
            if let Some(n) = part.strip_prefix("NAME=") {
                let _ = write!(def, "NAME={}_poa_copy", n.trim_matches('"'));
            } else if let Some(c) = part.strip_prefix("CENTER=") {
                let v: Vec<f64> = c.split(',').filter_map(|x| x.parse().ok()).collect();
                if v.len() == 2 {
                    let _ = write!(def, "CENTER={},{}", fmt(v[0] + d[0]), fmt(v[1] + d[1]));
                } else {
                    def.push_str(part);
                }
            } else if let Some(p) = part.strip_prefix("POLYGON=") {
                // [[x,y],[x,y],...]
                let nums: Vec<f64> = p
                    .split(|c: char| !(c.is_ascii_digit() || c == '.' || c == '-'))
                    .filter_map(|x| x.parse().ok())
                    .collect();
                let pts: Vec<String> = nums
                    .chunks(2)
                    .filter(|c| c.len() == 2)
                    .map(|c| format!("[{},{}]", fmt(c[0] + d[0]), fmt(c[1] + d[1])))
                    .collect();
                let _ = write!(def, "POLYGON=[{}]", pts.join(","));
            } else {
                def.push_str(part);
            }
        }
        out.extend_from_slice(def.as_bytes());
        out.extend_from_slice(&line[content.len()..]);
        if line.len() == content.len() {
            out.push(b'\n');
        }
    }
}

/// `G0`-`G3` with X/Y words get them shifted; everything else is copied.
fn shift_line(content: &[u8], d: [f64; 2]) -> Vec<u8> {
    let p = parse_line(content);
    let is_move = matches!(p.command, Command::Code { letter: b'G', number } if (0.0..=3.0).contains(&number));
    if !is_move || !(p.has(b'X') || p.has(b'Y')) {
        return content.to_vec();
    }
    // Words up to the comment; the comment stays as written.
    let code_end = content
        .iter()
        .position(|&b| b == b';' || b == b'(')
        .unwrap_or(content.len());
    let (code, rest) = content.split_at(code_end);
    let mut out = Vec::with_capacity(content.len() + 4);
    let mut i = 0;
    while i < code.len() {
        let c = code[i].to_ascii_uppercase();
        let prev_is_letter = i > 0 && code[i - 1].is_ascii_alphabetic();
        if (c == b'X' || c == b'Y') && !prev_is_letter {
            let start = i + 1;
            let mut end = start;
            while end < code.len()
                && (code[end].is_ascii_digit()
                    || matches!(code[end], b'.' | b'-' | b'+' | b' ')
                        && (end == start || code[end] != b' '))
            {
                end += 1;
            }
            let num = std::str::from_utf8(&code[start..end]).ok().map(str::trim);
            if let Some(v) = num.and_then(|n| n.parse::<f64>().ok()) {
                let dv = if c == b'X' { d[0] } else { d[1] };
                out.push(code[i]);
                out.extend_from_slice(fmt(v + dv).as_bytes());
                i = end;
                continue;
            }
        }
        out.push(code[i]);
        i += 1;
    }
    out.extend_from_slice(rest);
    out
}

/// The file's way of travelling (its [`TravelStyle`]), for the moves between the copies.
struct Junction {
    style: TravelStyle,
}

impl Junction {
    fn from_config(config: &SlicerConfig) -> Junction {
        let mut style = TravelStyle::from_config(config);
        // A lift clears the layer just printed even where the file travels without one.
        style.lift = style.lift.clamp(0.2, 5.0);
        Junction { style }
    }

    /// Moves from state `from` to where `to` (shifted by `d`) expects the nozzle: retracted,
    /// lifted, travelled, lowered and primed back to `to`'s retraction, with `to`'s E counter
    /// and feedrate.
    fn travel(
        &self,
        out: &mut Vec<u8>,
        from: &Machine,
        to: &Machine,
        d: [f64; 2],
        nl: &'static str,
    ) {
        let t = &self.style;
        let mut w = Writer::new(out, nl, from);
        let target_r = to.retracted.max(0.0);
        let travel_r = t.retract_length.max(from.retracted).max(target_r);
        if t.firmware_retraction {
            if !from.firmware_retracted {
                w.line("G10");
            }
        } else if travel_r - from.retracted > 1e-6 {
            w.e_at(-(travel_r - from.retracted), t.retract_speed);
        }
        let (p, q) = (from.position(), to.position());
        w.z_at(p[2].max(q[2]) + t.lift, Some(t.travel_speed));
        w.move_at([q[0] + d[0], q[1] + d[1]], t.travel_speed);
        w.z_at(q[2], None);
        if t.firmware_retraction {
            if !to.firmware_retracted {
                w.line("G11");
            }
        } else if travel_r - target_r > 1e-6 {
            w.e_at(travel_r - target_r, t.deretract_speed);
        }
        w.reset_e(to.e_logical());
        w.restore_feed(MmPerMin(to.feedrate().round()));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::layers::{LayerReader, ReaderOptions};

    #[test]
    fn moves_shift_and_nothing_else_does() {
        let d = [5.0, -1.0];
        let s = |t: &str| String::from_utf8(shift_line(t.as_bytes(), d)).unwrap();
        assert_eq!(
            s("G1 X10 Y20.5 E1.2 F600 ; X1"),
            "G1 X15 Y19.5 E1.2 F600 ; X1"
        );
        assert_eq!(s("G1X10Y20E1"), "G1X15Y19E1");
        assert_eq!(s("G2 X10 Y0 I5 J0 E1"), "G2 X15 Y-1 I5 J0 E1");
        assert_eq!(s("G1 Z0.4 F720"), "G1 Z0.4 F720");
        assert_eq!(s("M104 S200"), "M104 S200");
    }

    /// A two-layer part in absolute E with M486 labels on a 200 x 200 bed.
    const PART: &str = "; generated by PrusaSlicer 2.5.0\nM82\nG92 E0\n\
;LAYER_CHANGE\n;Z:0.2\nG1 Z0.2 F600\nG1 X10 Y10 F3000\nM486 S0\n;TYPE:External perimeter\n;WIDTH:0.45\n\
G1 X20 Y10 E1\nG1 X20 Y20 E2\nG1 X10 Y20 E3\nG1 X10 Y10 E4\nM486 S-1\nG1 E3.2 F2100\n\
;LAYER_CHANGE\n;Z:0.4\nG1 Z0.4 F600\nG1 X10 Y10 F3000\nG1 E4 F2100\nM486 S0\n;TYPE:External perimeter\n;WIDTH:0.45\n\
G1 X20 Y10 E5\nG1 X20 Y20 E6\nG1 X10 Y20 E7\nG1 X10 Y10 E8\nM486 S-1\nM104 S0 ; end\n\
; bed_shape = 0x0,200x0,200x200,0x200\n; retract_length = 0.8\n";

    #[test]
    fn a_copy_in_absolute_e_prints_the_same_filament_and_keeps_the_counter() {
        let config = SlicerConfig::parse(PART.as_bytes());
        let opts = AbOptions {
            offset: [50.0, 0.0],
            gap: 5.0,
            bed: None,
        };
        let plate = build(PART.as_bytes(), &config, &opts).unwrap();
        let text = String::from_utf8(plate.text.clone()).unwrap();
        assert_eq!(plate.copy_name, "id 1");
        assert!(text.contains("M486 S1\n"), "{text}");
        // The end G-code stays after the last layer's copy.
        assert!(text.trim_end().ends_with("; retract_length = 0.8"));
        let end = text.find("M104 S0").unwrap();
        assert!(text[..end].rfind("M486 S1").is_some());
        let mut reader = LayerReader::new(
            &plate.text[..],
            ReaderOptions {
                keep_raw: false,
                config,
            },
        );
        let layers: Vec<_> = reader.by_ref().map(|l| l.unwrap()).collect();
        let layers: Vec<_> = layers
            .iter()
            .filter(|l| l.kind == LayerKind::Layer)
            .collect();
        assert_eq!(layers.len(), 2);
        for l in layers {
            let e = |o: u32| -> f64 {
                l.paths
                    .iter()
                    .filter(|p| p.object == Some(o))
                    .map(|p| p.e())
                    .sum()
            };
            assert!(
                (e(0) - 4.0).abs() < 1e-9 && (e(1) - 4.0).abs() < 1e-9,
                "{}",
                l.index
            );
            let copy_x = l
                .paths
                .iter()
                .filter(|p| p.object == Some(1))
                .flat_map(|p| p.points.iter())
                .all(|p| p[0] >= 60.0 - 1e-9 && p[0] <= 70.0 + 1e-9);
            assert!(copy_x);
        }
        assert!(
            (plate.added_filament_mm - 8.0).abs() < 1e-6,
            "{}",
            plate.added_filament_mm
        );
        assert!(plate.added_time_s > 0.0);
    }

    #[test]
    fn refuses_relative_moves_and_unknown_beds() {
        let config = SlicerConfig::parse(PART.as_bytes());
        let opts = AbOptions {
            offset: [50.0, 0.0],
            gap: 5.0,
            bed: None,
        };
        let rel = PART.replacen("G1 X20 Y10 E1", "G91\nG1 X10 Y0 E1\nG90", 1);
        assert!(build(rel.as_bytes(), &config, &opts)
            .unwrap_err()
            .to_string()
            .contains("G91"));
        let no_bed = PART.replace("; bed_shape = 0x0,200x0,200x200,0x200\n", "");
        let cfg = SlicerConfig::parse(no_bed.as_bytes());
        assert!(build(no_bed.as_bytes(), &cfg, &opts)
            .unwrap_err()
            .to_string()
            .contains("--bed"));
        let with_bed = AbOptions {
            bed: Some([0.0, 0.0, 200.0, 200.0]),
            ..opts
        };
        assert!(build(no_bed.as_bytes(), &cfg, &with_bed).is_ok());
    }
}
