//! Settings: every key poa understands, where each value comes from, and validation.
//!
//! Input: an optional profile (built-in name or YAML file), the file's slicer configuration
//! (for choosing a profile by filament type) and command-line flags. Output: [`Effective`]
//! settings, each value with its [`Source`], turned into the options of the pipeline stages.
//!
//! Precedence, in this one place: built-in defaults < profile (`--profile`, else the one the
//! slicer's filament type names) < command-line flags (`--set key=value` and the named
//! flags). The slicer's own facts (widths, retraction, filament diameter, speeds used when a
//! key says `auto`) come from the file's config block, overridden by `SLIC3R_*` variables;
//! see [`crate::layers::SlicerConfig`].
//!
//! Invariants: a value that reaches the pipeline has passed its key's range check; an unknown
//! key, a wrong type or an out-of-range value is an error that names the key, where it came
//! from (file and line for profiles), the allowed values and, for a typo, the nearest key.

use std::fmt;

use serde::Serialize;

use crate::geometry::{DetectOptions, Tolerance};
use crate::layers::SlicerConfig;
use crate::poa::{BridgeMode, PoaSettings};

/// What values a key takes.
#[derive(Debug, Clone, Copy)]
pub enum Kind {
    /// A number in `min..=max`.
    Number { min: f64, max: f64 },
    /// A number in `min..=max`, or `auto`.
    Auto { min: f64, max: f64 },
    /// One of these words.
    Choice(&'static [&'static str]),
}

/// One setting.
#[derive(Debug)]
pub struct Spec {
    pub key: &'static str,
    pub kind: Kind,
    pub default: &'static str,
    pub unit: &'static str,
    pub help: &'static str,
}

/// Every key, in the order `poa config` shows them.
pub const SPECS: &[Spec] = &[
    Spec { key: "overlap", kind: Kind::Number { min: 0.05, max: 0.9 }, default: "0.4", unit: "", help: "share of a loop's width overlapping the previous loop" },
    Spec { key: "loop_speed", kind: Kind::Auto { min: 0.5, max: 500.0 }, default: "auto", unit: "mm/s", help: "loop speed (auto: the file's bridge speed)" },
    Spec { key: "perimeter_speed", kind: Kind::Auto { min: 0.5, max: 500.0 }, default: "auto", unit: "mm/s", help: "speed of the region's outer perimeter (auto: loop speed)" },
    Spec { key: "fan", kind: Kind::Number { min: 0.0, max: 100.0 }, default: "100", unit: "%", help: "part-cooling fan during loops" },
    Spec { key: "dwell", kind: Kind::Number { min: 0.0, max: 60.0 }, default: "0", unit: "s", help: "pause after each loop" },
    Spec { key: "min_loop_time", kind: Kind::Number { min: 0.0, max: 60.0 }, default: "0.5", unit: "s", help: "shortest time a loop takes: shorter loops (near a region's tip) are slowed, down to min_loop_speed, so each sets before the next leans on it" },
    Spec { key: "min_loop_speed", kind: Kind::Auto { min: 1.0, max: 500.0 }, default: "auto", unit: "mm/s", help: "slowest speed a loop is slowed to for its minimum time (auto: the file's minimum print speed for cooling, PrusaSlicer's min_print_speed, OrcaSlicer's slow_down_min_speed or Cura's cool_min_speed, 10 mm/s where Cura leaves it at its default; not under 5 mm/s; 5 mm/s where the file states none)" },
    Spec { key: "flow_factor", kind: Kind::Number { min: 0.5, max: 2.0 }, default: "1.0", unit: "", help: "extrusion multiplier for poa's strands" },
    Spec { key: "perimeter_inset", kind: Kind::Number { min: 0.0, max: 2.0 }, default: "0.05", unit: "mm", help: "how far the region's outer perimeter is pulled inward" },
    Spec { key: "temperature_offset", kind: Kind::Number { min: -50.0, max: 50.0 }, default: "0", unit: "C", help: "nozzle temperature change while printing loops" },
    Spec { key: "bridges", kind: Kind::Choice(&["auto", "keep", "poa"]), default: "auto", unit: "", help: "rewrite bridges whose slicer strands would be in air (auto), all bridges (poa), or none (keep)" },
    Spec { key: "tolerance", kind: Kind::Auto { min: 0.0, max: 10.0 }, default: "auto", unit: "mm", help: "distance from the layer below that still counts as supported (auto: half the external perimeter width, plus the fuzzy skin thickness where the file has fuzzy skin)" },
    Spec { key: "overhang_angle", kind: Kind::Auto { min: 0.0, max: 89.9 }, default: "auto", unit: "deg", help: "the tolerance as an overhang angle from vertical (overrides tolerance)" },
    Spec { key: "min_width", kind: Kind::Auto { min: 0.0, max: 50.0 }, default: "auto", unit: "mm", help: "narrowest region rewritten (auto: a tenth of a perimeter width, so gradual overhangs are rewritten too)" },
    Spec { key: "min_area", kind: Kind::Number { min: 0.0, max: 100_000.0 }, default: "0.2", unit: "mm2", help: "smallest region rewritten; those under 1 mm2 only where the slicer's strands over them would be in air" },
];

/// The values a key takes and its default, as `--help`, `poa config` and `poa profiles show`
/// state them: `0.05-0.9`, `auto or 0.5-500 mm/s`, `keep|poa`.
pub fn range_text(spec: &Spec) -> String {
    let unit = if spec.unit.is_empty() {
        String::new()
    } else {
        format!(" {}", spec.unit)
    };
    match spec.kind {
        Kind::Number { min, max } => format!("{min} to {max}{unit}"),
        Kind::Auto { min, max } => format!("auto or {min} to {max}{unit}"),
        Kind::Choice(words) => words.join("|"),
    }
}

/// The `--help` text of the flag for `key`, made from its entry in [`SPECS`]: what it does,
/// the values it takes and its default.
pub fn flag_help(key: &str) -> String {
    match spec(key) {
        Some(s) => format!(
            "{} [{}; default {}]",
            capitalised(s.help),
            range_text(s),
            s.default
        ),
        None => key.to_string(),
    }
}

fn capitalised(text: &str) -> String {
    let mut c = text.chars();
    c.next()
        .map(|f| f.to_uppercase().chain(c).collect())
        .unwrap_or_default()
}

/// The rewrite's settings at the table's defaults: the table is the one place they are written.
impl Default for PoaSettings {
    fn default() -> Self {
        Effective::defaults().poa_settings()
    }
}

/// Built-in profiles: name, aliases (slicer filament types) and YAML text.
pub const BUILTIN: &[(&str, &[&str], &str)] = &[
    (
        "pla",
        &["PLA", "PLA+", "PHA"],
        include_str!("profiles/pla.yaml"),
    ),
    (
        "petg",
        &["PETG", "PET", "PCTG", "CPE"],
        include_str!("profiles/petg.yaml"),
    ),
    (
        "abs",
        &["ABS", "ASA", "HIPS", "PC"],
        include_str!("profiles/abs.yaml"),
    ),
    (
        "tpu",
        &["TPU", "FLEX", "TPE"],
        include_str!("profiles/tpu.yaml"),
    ),
];

/// A checked value.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Value {
    Number(f64),
    Word(String),
}

impl fmt::Display for Value {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Value::Number(x) => write!(f, "{x}"),
            Value::Word(w) => f.write_str(w),
        }
    }
}

/// Where a value came from.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Source {
    Default,
    Profile(String),
    Flag,
}

impl fmt::Display for Source {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Source::Default => f.write_str("default"),
            Source::Profile(p) => write!(f, "profile {p}"),
            Source::Flag => f.write_str("command line"),
        }
    }
}

/// A settings error, worded for the user.
#[derive(Debug, Clone, PartialEq)]
pub struct SettingsError(pub String);

impl fmt::Display for SettingsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for SettingsError {}

fn spec(key: &str) -> Option<&'static Spec> {
    SPECS.iter().find(|s| s.key == key)
}

/// "unknown key `x`; did you mean `y`?"
fn unknown(key: &str, place: &str) -> SettingsError {
    let nearest = SPECS
        .iter()
        .map(|s| (strsim::levenshtein(key, s.key), s.key))
        .min()
        .filter(|(d, _)| *d <= 3);
    let hint = match nearest {
        Some((_, k)) => format!("; did you mean `{k}`?"),
        None => format!(
            "; known keys: {}",
            SPECS.iter().map(|s| s.key).collect::<Vec<_>>().join(", ")
        ),
    };
    SettingsError(format!("{place}unknown key `{key}`{hint}"))
}

fn allowed(kind: Kind) -> String {
    match kind {
        Kind::Number { min, max } => format!("a number from {min} to {max}"),
        Kind::Auto { min, max } => format!("`auto` or a number from {min} to {max}"),
        Kind::Choice(words) => format!("one of {}", words.join(", ")),
    }
}

/// Checks a value given as text (flags) for `key`.
pub fn check_text(key: &str, text: &str, place: &str) -> Result<Value, SettingsError> {
    let s = spec(key).ok_or_else(|| unknown(key, place))?;
    let t = text.trim();
    let bad = |got: &str| {
        SettingsError(format!(
            "{place}`{key}` must be {} (got {got})",
            allowed(s.kind)
        ))
    };
    match s.kind {
        Kind::Number { min, max } | Kind::Auto { min, max } => {
            if matches!(s.kind, Kind::Auto { .. }) && t.eq_ignore_ascii_case("auto") {
                return Ok(Value::Word("auto".into()));
            }
            let x: f64 = t.parse().map_err(|_| bad(&format!("`{t}`")))?;
            if !x.is_finite() || x < min || x > max {
                return Err(bad(t));
            }
            Ok(Value::Number(x))
        }
        Kind::Choice(words) => {
            let w = t.to_ascii_lowercase();
            if words.contains(&w.as_str()) {
                Ok(Value::Word(w))
            } else {
                Err(bad(&format!("`{t}`")))
            }
        }
    }
}

/// Parses and checks a profile's YAML. `origin` names it in messages (a path or a built-in).
pub fn parse_profile(
    text: &str,
    origin: &str,
) -> Result<Vec<(&'static str, Value)>, SettingsError> {
    let doc: serde_yaml::Value = serde_yaml::from_str(text)
        .map_err(|e| SettingsError(format!("{origin}: not valid YAML: {e}")))?;
    let map = match doc {
        serde_yaml::Value::Mapping(m) => m,
        serde_yaml::Value::Null => return Ok(Vec::new()),
        _ => {
            return Err(SettingsError(format!(
                "{origin}: a profile is a list of `key: value` lines"
            )))
        }
    };
    let mut out = Vec::new();
    for (k, v) in map {
        let Some(key) = k.as_str() else {
            return Err(SettingsError(format!(
                "{origin}: keys must be words, got {k:?}"
            )));
        };
        let place = format!("{origin} line {}: ", line_of(text, key));
        let text_value = match &v {
            serde_yaml::Value::Number(n) => n.to_string(),
            serde_yaml::Value::String(s) => s.clone(),
            serde_yaml::Value::Null => "auto".to_string(),
            serde_yaml::Value::Bool(b) => format!("`{b}`"),
            other => format!("{other:?}"),
        };
        let s = spec(key).ok_or_else(|| unknown(key, &place))?;
        let value = check_text(key, &text_value, &place)?;
        out.push((s.key, value));
    }
    Ok(out)
}

/// The 1-based line where `key:` is written in a YAML text (0 when not found).
fn line_of(text: &str, key: &str) -> usize {
    text.lines()
        .position(|l| {
            let t = l.trim_start();
            t.strip_prefix(key)
                .is_some_and(|rest| rest.trim_start().starts_with(':'))
        })
        .map(|i| i + 1)
        .unwrap_or(0)
}

/// The built-in profile for a name or a slicer filament type.
pub fn builtin(name: &str) -> Option<(&'static str, &'static str)> {
    let n = name.trim();
    BUILTIN
        .iter()
        .find(|(p, aliases, _)| {
            p.eq_ignore_ascii_case(n) || aliases.iter().any(|a| a.eq_ignore_ascii_case(n))
        })
        .map(|(p, _, text)| (*p, *text))
}

/// A built-in profile as `poa profiles show` prints it: its YAML, each key's line followed by
/// the values the key takes and its default, from [`SPECS`].
pub fn builtin_annotated(name: &str) -> Option<String> {
    let (_, text) = builtin(name)?;
    let mut out = String::with_capacity(text.len() + 1024);
    for line in text.lines() {
        out.push_str(line);
        let key = line.split(':').next().unwrap_or("").trim();
        if !line.starts_with('#') && line.contains(':') {
            if let Some(s) = spec(key) {
                out.push_str(&format!("  # {}; default {}", range_text(s), s.default));
            }
        }
        out.push('\n');
    }
    Some(out)
}

/// A profile's checked entries.
pub type Entries = Vec<(&'static str, Value)>;

/// A profile chosen by the user: a built-in name or a YAML file.
pub fn load_profile(name_or_path: &str) -> Result<(String, Entries), SettingsError> {
    let path = std::path::Path::new(name_or_path);
    if path.is_file() {
        let text = std::fs::read_to_string(path)
            .map_err(|e| SettingsError(format!("cannot read profile {}: {e}", path.display())))?;
        let origin = path.display().to_string();
        return Ok((origin.clone(), parse_profile(&text, &origin)?));
    }
    match builtin(name_or_path) {
        Some((name, text)) => Ok((name.to_string(), parse_profile(text, name)?)),
        None => Err(SettingsError(format!(
            "no profile `{name_or_path}`: not a file, and the built-in profiles are {}",
            BUILTIN.iter().map(|b| b.0).collect::<Vec<_>>().join(", ")
        ))),
    }
}

/// The settings in force, each with its source.
#[derive(Debug, Clone, Serialize)]
pub struct Effective {
    pub profile: Option<String>,
    pub values: Vec<EffectiveValue>,
}

#[derive(Debug, Clone, Serialize)]
pub struct EffectiveValue {
    pub key: &'static str,
    pub value: Value,
    pub source: Source,
}

/// Resolves settings: defaults < profile < flags. With no `profile`, the slicer's filament
/// type (`filament_type`, e.g. from `SLIC3R_FILAMENT_TYPE`) picks a built-in one if it names
/// one. `flags` are `(key, text)` pairs in command-line order.
pub fn resolve(
    profile: Option<&str>,
    config: &SlicerConfig,
    flags: &[(String, String)],
) -> Result<Effective, SettingsError> {
    let mut values = Effective::defaults().values;
    let chosen = match profile {
        Some(p) => Some(load_profile(p)?),
        None => config
            .get("filament_type")
            .and_then(|t| t.split([';', ',']).next())
            .and_then(builtin)
            .map(|(name, text)| {
                parse_profile(text, name).map(|v| (format!("{name} (from the filament type)"), v))
            })
            .transpose()?,
    };
    let mut profile_name = None;
    if let Some((name, entries)) = chosen {
        for (key, value) in entries {
            if let Some(e) = values.iter_mut().find(|e| e.key == key) {
                e.value = value;
                e.source = Source::Profile(name.clone());
            }
        }
        profile_name = Some(name);
    }
    for (key, text) in flags {
        let value = check_text(key, text, "command line: ")?;
        if let Some(e) = values.iter_mut().find(|e| e.key == key.as_str()) {
            e.value = value;
            e.source = Source::Flag;
        }
    }
    Ok(Effective {
        profile: profile_name,
        values,
    })
}

impl Effective {
    fn get(&self, key: &str) -> &Value {
        &self
            .values
            .iter()
            .find(|e| e.key == key)
            .expect("every key has a value")
            .value
    }

    fn number(&self, key: &str) -> Option<f64> {
        match self.get(key) {
            Value::Number(x) => Some(*x),
            Value::Word(_) => None,
        }
    }

    /// A number key's value: every key has one (its default at least), so the fallback is
    /// the table's default, never a second copy of it.
    fn required(&self, key: &str) -> f64 {
        self.number(key)
            .or_else(|| spec(key).and_then(|s| s.default.parse().ok()))
            .unwrap_or(0.0)
    }

    /// Every key at its default from [`SPECS`].
    pub fn defaults() -> Effective {
        Effective {
            profile: None,
            values: SPECS
                .iter()
                .map(|s| EffectiveValue {
                    key: s.key,
                    value: check_text(s.key, s.default, "")
                        .unwrap_or(Value::Word(s.default.into())),
                    source: Source::Default,
                })
                .collect(),
        }
    }

    /// The rewrite's settings.
    pub fn poa_settings(&self) -> PoaSettings {
        PoaSettings {
            overlap: self.required("overlap"),
            loop_speed: self.number("loop_speed"),
            perimeter_speed: self.number("perimeter_speed"),
            // The table states percent; the planner and writer take a share.
            fan: self.required("fan") / 100.0,
            dwell: self.required("dwell"),
            min_loop_time: self.required("min_loop_time"),
            min_loop_speed: self.number("min_loop_speed"),
            flow_factor: self.required("flow_factor"),
            perimeter_inset: self.required("perimeter_inset"),
            temperature_offset: self.required("temperature_offset"),
            bridges: match self.get("bridges") {
                Value::Word(w) if w == "poa" => BridgeMode::Poa,
                Value::Word(w) if w == "keep" => BridgeMode::Keep,
                _ => BridgeMode::Auto,
            },
        }
    }

    /// Region detection settings for a file with `config`.
    pub fn detect_options(&self, config: &SlicerConfig) -> DetectOptions {
        let mut o = DetectOptions::for_file(config);
        if let Some(t) = self.number("tolerance") {
            o.tolerance = Tolerance::Distance(t);
        }
        if let Some(a) = self.number("overhang_angle") {
            o.tolerance = Tolerance::Angle(a);
        }
        o.min_width = self.number("min_width");
        o.min_area = self.required("min_area");
        o
    }

    /// One line for the file's header comment.
    pub fn summary(&self) -> String {
        self.values
            .iter()
            .map(|e| format!("{}={}", e.key, e.value))
            .collect::<Vec<_>>()
            .join(" ")
    }
}

/// The slicer settings poa reads, as `poa config` lists them.
const SLICER_FACTS: &[&str] = &[
    "filament_type",
    "filament_diameter",
    "nozzle_diameter",
    "layer_height",
    "external_perimeter_extrusion_width",
    "bridge_speed",
    "retract_length",
    "retract_lift",
    "travel_speed",
    "use_relative_e_distances",
];

/// `poa config FILE` as text: the settings in force with their sources, then the slicer
/// settings poa reads from the file and where each came from.
pub fn describe(eff: &Effective, config: &SlicerConfig) -> String {
    let poa = eff.poa_settings();
    let motion = crate::emit::Motion::from_config(config, &poa);
    let detect = eff.detect_options(config);
    let height = config.layer_height().unwrap_or(0.2);
    let tolerance = detect.tolerance_at(height);
    // What `auto` comes to for this file, and from where.
    let resolved = |key: &str| -> Option<(String, &'static str)> {
        let bridge = if config.number("bridge_speed").is_some_and(|v| v > 0.0) {
            "auto: the file's bridge_speed"
        } else {
            "auto: no bridge_speed in the file"
        };
        Some(match key {
            "loop_speed" => (motion.loop_speed.to_string(), bridge),
            "perimeter_speed" => (motion.perimeter_speed.to_string(), "auto: loop_speed"),
            "min_loop_speed" => (
                motion.cooling_floor.to_string(),
                if config.stated_cooling_min_speed().is_some() {
                    "auto: the file's min print speed"
                } else if config.cooling_min_speed().is_some() {
                    "auto: Cura's default min speed"
                } else {
                    "auto: none in the file"
                },
            ),
            "tolerance" => (
                format!("{tolerance:.3} mm"),
                if detect.fuzzy_skin > 0.0 {
                    "auto: half the external perimeter width plus the fuzzy skin thickness"
                } else {
                    "auto: half the external perimeter width"
                },
            ),
            "overhang_angle" => (
                format!("{:.1} deg", (tolerance / height).atan().to_degrees()),
                "auto: from the tolerance",
            ),
            "min_width" => (
                format!("{:.3} mm", detect.min_width()),
                "auto: a tenth of the external perimeter width",
            ),
            _ => return None,
        })
    };
    let mut t = match &eff.profile {
        Some(p) => format!("profile: {p}\n"),
        None => "profile: none (built-in defaults)\n".to_string(),
    };
    for e in &eff.values {
        let Some(s) = spec(e.key) else { continue };
        let (value, source) = match (&e.value, resolved(e.key)) {
            (Value::Word(w), Some((v, why))) if w == "auto" => (v, why.to_string()),
            _ => (
                format!("{} {}", e.value, s.unit).trim().to_string(),
                e.source.to_string(),
            ),
        };
        t.push_str(&format!(
            "  {:<20} {:<12} {:<40} [{}; default {}]\n",
            e.key,
            value,
            source,
            range_text(s),
            s.default
        ));
    }
    t.push_str("from the slicer (config block, overridden by SLIC3R_* variables):\n");
    for key in SLICER_FACTS {
        let v = config.get(key).unwrap_or("(not set)");
        let src = if config.is_from_env(key) {
            "SLIC3R_ variable"
        } else if config.inferred().iter().any(|(k, _)| k == key) {
            "inferred from the walls' E"
        } else if config.get(key).is_some() {
            "file"
        } else {
            ""
        };
        t.push_str(&format!("  {key:<36} {v:<12} {src}\n"));
    }
    t
}

/// `poa profiles`: the built-in profiles and the filament types that pick each.
pub fn profiles_text() -> String {
    let mut t = String::from("built-in profiles (poa profiles show NAME prints one):\n");
    for (name, aliases, _) in BUILTIN {
        t.push_str(&format!("  {name:<6} for {}\n", aliases.join(", ")));
    }
    t.push_str("without --profile, poa picks the one matching the slicer's filament type\n");
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg(pairs: &[(&str, &str)]) -> SlicerConfig {
        let mut c = SlicerConfig::default();
        c.apply_env(
            pairs
                .iter()
                .map(|(k, v)| (format!("SLIC3R_{}", k.to_uppercase()), v.to_string())),
        );
        c
    }

    fn value(e: &Effective, key: &str) -> (Value, Source) {
        let v = e.values.iter().find(|v| v.key == key).unwrap();
        (v.value.clone(), v.source.clone())
    }

    #[test]
    fn every_builtin_profile_parses_and_sets_every_key() {
        for (name, _, text) in BUILTIN {
            let entries = parse_profile(text, name).unwrap();
            for s in SPECS {
                assert!(
                    entries.iter().any(|(k, _)| *k == s.key),
                    "{name} lacks {}",
                    s.key
                );
            }
        }
    }

    #[test]
    fn precedence_default_profile_flag() {
        let none = resolve(None, &cfg(&[]), &[]).unwrap();
        assert_eq!(value(&none, "fan"), (Value::Number(100.0), Source::Default));
        let petg = resolve(Some("petg"), &cfg(&[]), &[]).unwrap();
        assert_eq!(
            value(&petg, "fan"),
            (Value::Number(60.0), Source::Profile("petg".into()))
        );
        let flag = resolve(Some("petg"), &cfg(&[]), &[("fan".into(), "75".into())]).unwrap();
        assert_eq!(value(&flag, "fan"), (Value::Number(75.0), Source::Flag));
        // A key the profile does not mention keeps its default.
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("mine.yaml");
        std::fs::write(&p, "dwell: 2\n").unwrap();
        let mine = resolve(Some(p.to_str().unwrap()), &cfg(&[]), &[]).unwrap();
        assert_eq!(value(&mine, "dwell").0, Value::Number(2.0));
        assert_eq!(value(&mine, "fan"), (Value::Number(100.0), Source::Default));
    }

    #[test]
    fn filament_type_picks_a_profile() {
        let e = resolve(None, &cfg(&[("filament_type", "ASA")]), &[]).unwrap();
        assert!(e.profile.as_deref().unwrap().starts_with("abs"));
        assert_eq!(value(&e, "fan").0, Value::Number(40.0));
        // An explicit profile wins over the filament type.
        let e = resolve(Some("pla"), &cfg(&[("filament_type", "ASA")]), &[]).unwrap();
        assert_eq!(value(&e, "fan").0, Value::Number(100.0));
    }

    #[test]
    fn validation_messages() {
        let e = parse_profile("fan: 100\noverlapp: 0.4\n", "my.yaml").unwrap_err();
        assert_eq!(
            e.0,
            "my.yaml line 2: unknown key `overlapp`; did you mean `overlap`?"
        );
        let e = parse_profile("overlap: 1.5\n", "my.yaml").unwrap_err();
        assert_eq!(
            e.0,
            "my.yaml line 1: `overlap` must be a number from 0.05 to 0.9 (got 1.5)"
        );
        let e = parse_profile("\n\nfan: high\n", "my.yaml").unwrap_err();
        assert_eq!(
            e.0,
            "my.yaml line 3: `fan` must be a number from 0 to 100 (got `high`)"
        );
        let e = parse_profile("bridges: maybe\n", "p.yaml").unwrap_err();
        assert_eq!(
            e.0,
            "p.yaml line 1: `bridges` must be one of auto, keep, poa (got `maybe`)"
        );
        let e = parse_profile("- a\n- b\n", "p.yaml").unwrap_err();
        assert!(e.0.contains("key: value"), "{}", e.0);
        let e = resolve(None, &cfg(&[]), &[("loop_sped".into(), "10".into())]).unwrap_err();
        assert_eq!(
            e.0,
            "command line: unknown key `loop_sped`; did you mean `loop_speed`?"
        );
        let e = resolve(Some("nylon"), &cfg(&[]), &[]).unwrap_err();
        assert!(e.0.contains("pla, petg, abs, tpu"), "{}", e.0);
        let e = parse_profile("fan: [1, 2]\n", "p.yaml").unwrap_err();
        assert!(
            e.0.starts_with("p.yaml line 1: `fan` must be a number"),
            "{}",
            e.0
        );
    }

    #[test]
    fn auto_values() {
        let e = resolve(None, &cfg(&[]), &[("tolerance".into(), "0.3".into())]).unwrap();
        let o = e.detect_options(&cfg(&[]));
        assert_eq!(o.tolerance, Tolerance::Distance(0.3));
        let e = resolve(None, &cfg(&[]), &[("loop_speed".into(), "auto".into())]).unwrap();
        assert_eq!(e.poa_settings().loop_speed, None);
    }
}
