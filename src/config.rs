//! Slicer settings a file carries about itself.
//!
//! Input: the head and tail of a G-code file (config blocks sit at the end for PrusaSlicer,
//! SuperSlicer, OrcaSlicer and Slic3r, in the header for Simplify3D and Cura) and the process
//! environment (`SLIC3R_*`, exported by PrusaSlicer-family slicers to post-processing scripts).
//! Output: a [`SlicerConfig`] with typed getters and safe defaults.
//!
//! Precedence: file values < `SLIC3R_*` environment values (the slicer's values at export time).

use std::collections::HashMap;

/// Key/value settings, keys in PrusaSlicer spelling.
#[derive(Debug, Clone, Default)]
pub struct SlicerConfig {
    values: HashMap<String, String>,
    /// Keys that came from the environment.
    from_env: Vec<String>,
    /// Keys poa inferred from the file's moves (the file states none), with why.
    inferred: Vec<(String, String)>,
    /// The file names CuraEngine as its maker (`;Generated with Cura_SteamEngine`): Cura
    /// writes only the settings the user changed, so a setting it leaves out has Cura's
    /// default.
    cura: bool,
}

/// Cura's default `cool_min_speed` (mm/s, its `fdmprinter` definition).
const CURA_COOL_MIN_SPEED: f64 = 10.0;

/// How many bytes of the head and of the tail of a file hold its configuration.
pub const HEAD_BYTES: u64 = 64 * 1024;
pub const TAIL_BYTES: u64 = 512 * 1024;
/// Most of Cura's `;SETTING_3` profile read (a few kilobytes in practice).
const CURA_SETTINGS_BYTES: usize = 256 * 1024;

impl SlicerConfig {
    /// Parses `; key = value` lines (PrusaSlicer family, Slic3r, Orca), Simplify3D's
    /// `;   key,value` header lines and Cura's `;Layer height: 0.2` header lines.
    pub fn parse(text: &[u8]) -> Self {
        let mut cfg = SlicerConfig::default();
        cfg.add_text(text);
        cfg
    }

    pub fn add_text(&mut self, text: &[u8]) {
        // Cura's front end serialises the settings the user changed into `;SETTING_3 ` lines
        // at the end of the file, cut at fixed widths: joined, then read after the rest.
        let mut cura_settings = String::new();
        for line in text.split(|&b| b == b'\n') {
            let Some(rest) = line.strip_prefix(b";") else {
                continue;
            };
            let Ok(rest) = std::str::from_utf8(rest) else {
                continue;
            };
            // Cut at fixed widths: a line's spaces may be inside a value.
            if let Some(payload) = rest.strip_prefix("SETTING_3 ") {
                if cura_settings.len() < CURA_SETTINGS_BYTES {
                    cura_settings.push_str(payload.trim_end_matches(['\r', '\n']));
                }
                continue;
            }
            let rest = rest.trim();
            if rest.starts_with("Generated with Cura_SteamEngine") {
                self.cura = true;
            }
            if let Some((k, v)) = rest.split_once(" = ") {
                let k = k.trim();
                if !k.is_empty() && k.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_') {
                    self.values.insert(k.to_string(), v.trim().to_string());
                } else if let Some(mode) = k.strip_prefix("estimated printing time") {
                    // The statistics footer: `; estimated printing time (normal mode) = 35m 49s`.
                    let key = if mode.contains("silent") {
                        "estimated_printing_time_silent"
                    } else {
                        "estimated_printing_time"
                    };
                    self.values.insert(key.to_string(), v.trim().to_string());
                }
            } else if let Some((k, v)) = rest.split_once(',') {
                // Simplify3D: `;   filamentDiameters,1.75`
                let key = match k.trim() {
                    "filamentDiameters" => "filament_diameter",
                    "extruderDiameter" => "nozzle_diameter",
                    "layerHeight" => "layer_height",
                    "extruderWidth" => "extrusion_width",
                    "useRelativeEDistances" | "relativeEdistances" => "use_relative_e_distances",
                    _ => continue,
                };
                self.values.insert(key.to_string(), v.trim().to_string());
            } else if let Some(v) = rest.strip_prefix("TIME:").filter(|v| v.trim() != "6666") {
                // Cura's header: `;TIME:1604` (seconds). CuraEngine run on its own leaves the
                // placeholder 6666 that Cura's front end fills in.
                self.values.insert(
                    "estimated_printing_time".to_string(),
                    format!("{}s", v.trim()),
                );
            } else if let Some(v) = rest.strip_prefix("FLAVOR:") {
                // Cura's header: `;FLAVOR:UltiGCode`.
                self.values
                    .entry("gcode_flavor".to_string())
                    .or_insert_with(|| v.trim().to_string());
            } else if let Some(v) = rest
                .strip_prefix("EXTRUDER_TRAIN.0.NOZZLE.DIAMETER:")
                .or_else(|| rest.strip_prefix("EXTRUDER_TRAIN.0.MATERIAL.DIAMETER:"))
            {
                // Cura's Griffin header (Ultimaker S-line, UM3).
                let key = if rest.contains("NOZZLE") {
                    "nozzle_diameter"
                } else {
                    "filament_diameter"
                };
                self.values
                    .entry(key.to_string())
                    .or_insert_with(|| v.trim().to_string());
            } else if let Some(v) = rest.strip_prefix("Layer height:") {
                self.values
                    .insert("layer_height".to_string(), v.trim().to_string());
            }
        }
        self.add_cura_settings(&cura_settings);
    }

    /// Reads the `key = value` lines of Cura's serialised profile (`\n`-separated inside a
    /// JSON string); a value the file states elsewhere is kept.
    fn add_cura_settings(&mut self, text: &str) {
        for piece in text.split("\\n") {
            let Some((k, v)) = piece.split_once(" = ") else {
                continue;
            };
            let k = k.trim();
            if !k.is_empty() && k.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_') {
                // The file escapes the JSON's own escapes: `\\n` ends a line.
                let v = v.trim().trim_end_matches('\\').trim();
                self.values
                    .entry(k.to_string())
                    .or_insert_with(|| v.to_string());
            }
        }
    }

    /// Overrides with `SLIC3R_<KEY>` variables from `vars`.
    pub fn apply_env<I: IntoIterator<Item = (String, String)>>(&mut self, vars: I) {
        for (k, v) in vars {
            if let Some(key) = k.strip_prefix("SLIC3R_") {
                let key = key.to_ascii_lowercase();
                self.from_env.push(key.clone());
                self.values.insert(key, v);
            }
        }
    }

    /// The value of a setting by PrusaSlicer's name, or by OrcaSlicer's and Bambu Studio's
    /// name for it where the file has only that ([`ORCA_NAMES`]).
    pub fn get(&self, key: &str) -> Option<&str> {
        self.values.get(self.named(key)).map(String::as_str)
    }

    /// The name the file gives the setting PrusaSlicer calls `key`.
    fn named<'k>(&self, key: &'k str) -> &'k str {
        if self.values.contains_key(key) {
            return key;
        }
        ORCA_NAMES
            .iter()
            .find(|(prusa, orca)| *prusa == key && self.values.contains_key(*orca))
            .map_or(key, |(_, orca)| orca)
    }

    /// Sets `key` to a value poa inferred (the file and the environment state none), saying
    /// why in `why` (shown by `poa info` and after `poa process`).
    pub fn infer(&mut self, key: &str, value: &str, why: String) {
        self.values.insert(key.to_string(), value.to_string());
        self.inferred.push((key.to_string(), why));
    }

    /// The values inferred by [`SlicerConfig::infer`]: (key, why).
    pub fn inferred(&self) -> &[(String, String)] {
        &self.inferred
    }

    pub fn is_from_env(&self, key: &str) -> bool {
        self.from_env.iter().any(|k| k == key)
    }

    pub fn len(&self) -> usize {
        self.values.len()
    }

    pub fn is_empty(&self) -> bool {
        self.values.is_empty()
    }

    /// First number of a (possibly comma-separated, per-extruder) value.
    pub fn number(&self, key: &str) -> Option<f64> {
        let v = self.get(key)?;
        let first = v.split([',', ';', '|']).next()?.trim();
        let x: f64 = first.trim_end_matches("mm").trim().parse().ok()?;
        x.is_finite().then_some(x)
    }

    /// Sparse infill density in percent (PrusaSlicer and its forks' `fill_density`, `15%`;
    /// Cura's `infill_sparse_density` where a header states it).
    pub fn fill_density(&self) -> Option<f64> {
        let v = self
            .get("fill_density")
            .or_else(|| self.get("infill_sparse_density"))?;
        let x: f64 = v.trim().trim_end_matches('%').trim().parse().ok()?;
        (x.is_finite() && (0.0..=100.0).contains(&x)).then_some(x)
    }

    pub fn bool(&self, key: &str) -> Option<bool> {
        match self.get(key)?.trim() {
            "1" | "true" | "True" => Some(true),
            "0" | "false" | "False" => Some(false),
            _ => None,
        }
    }

    /// The filament diameter the file's E is measured in: as stated, else 2.85 mm for Cura's
    /// Griffin flavour (Ultimaker's printers, which take no other; the header names the
    /// nozzle but not the filament), else 1.75 mm.
    pub fn filament_diameter(&self) -> f64 {
        self.number("filament_diameter")
            .filter(|d| (0.5..=5.0).contains(d))
            .unwrap_or_else(|| {
                if self
                    .get("gcode_flavor")
                    .is_some_and(|f| f.trim().eq_ignore_ascii_case("griffin"))
                {
                    2.85
                } else {
                    1.75
                }
            })
    }

    /// Whether the 1.75 mm of [`SlicerConfig::filament_diameter`] is a guess: the file (or
    /// the environment) states no diameter, nor is E volumetric or Cura's Griffin flavour.
    pub fn filament_diameter_unstated(&self) -> bool {
        self.diameter_assumed(1.75)
    }

    /// Whether the 2.85 mm of [`SlicerConfig::filament_diameter`] is Cura's Griffin flavour's
    /// (nothing states a diameter): a Griffin file sliced for another printer may be in
    /// 1.75 mm filament.
    pub fn filament_diameter_griffin_assumed(&self) -> bool {
        self.diameter_assumed(2.85)
    }

    /// Nothing states the filament diameter, E is not volumetric, and `d` is what is assumed.
    fn diameter_assumed(&self, d: f64) -> bool {
        self.number("filament_diameter")
            .filter(|d| (0.5..=5.0).contains(d))
            .is_none()
            && !self.volumetric_e()
            && self.filament_diameter() == d
    }

    pub fn nozzle_diameter(&self) -> f64 {
        self.number("nozzle_diameter")
            .filter(|d| (0.05..=3.0).contains(d))
            .unwrap_or(0.4)
    }

    /// How far the first layer is drawn in from the outline (mm): PrusaSlicer's and
    /// OrcaSlicer's `elefant_foot_compensation`; SuperSlicer's `first_layer_size_compensation`
    /// and Cura's `xy_offset_layer_0` state it negative. 0 when unset or out of range.
    pub fn elephant_foot(&self) -> f64 {
        let drawn_in = |key: &str| self.number(key).map(|v| -v);
        self.number("elefant_foot_compensation")
            .or_else(|| drawn_in("first_layer_size_compensation"))
            .or_else(|| drawn_in("xy_offset_layer_0"))
            .filter(|v| (0.0..=2.0).contains(v))
            .unwrap_or(0.0)
    }

    /// How far fuzzy skin moves the walls' points off the outline (mm, either way), 0 without
    /// it: PrusaSlicer and its forks' `fuzzy_skin` (anything but `none`) with
    /// `fuzzy_skin_thickness`, Cura's `magic_fuzzy_skin_enabled` with
    /// `magic_fuzzy_skin_thickness` (its front end's `;SETTING_3` profile). Both slicers move
    /// each point by a random amount up to the thickness inwards or outwards. A stated
    /// thickness out of 0-2 mm is ignored; fuzzy skin stated on but no thickness read is
    /// taken at both slicers' default, 0.3 mm.
    pub fn fuzzy_skin(&self) -> f64 {
        let thickness = |key: &str| {
            self.number(key)
                .filter(|t| (0.0..=2.0).contains(t))
                .unwrap_or(0.3)
        };
        let prusa = self.get("fuzzy_skin").map(str::trim);
        if prusa.is_some_and(|v| !v.is_empty() && !v.eq_ignore_ascii_case("none")) {
            return thickness("fuzzy_skin_thickness");
        }
        if self.bool("magic_fuzzy_skin_enabled") == Some(true) {
            return thickness("magic_fuzzy_skin_thickness");
        }
        0.0
    }

    pub fn layer_height(&self) -> Option<f64> {
        self.number("layer_height").filter(|h| *h > 0.0 && *h < 5.0)
    }

    /// A width setting in mm, resolving PrusaSlicer's `0` (auto) and percentages (of the
    /// nozzle diameter, or of the layer height for `first_layer_extrusion_width`).
    pub fn width(&self, key: &str) -> Option<f64> {
        let v = self.get(key)?.trim();
        let nozzle = self.nozzle_diameter();
        if let Some(p) = v.strip_suffix('%') {
            let p: f64 = p.trim().parse().ok()?;
            return Some(p / 100.0 * nozzle).filter(|w| *w > 0.0);
        }
        let w: f64 = v.trim_end_matches("mm").parse().ok()?;
        (w > 0.0 && w.is_finite()).then_some(w)
    }

    /// Whether the file states the external perimeter width: in mm or percent (or the general
    /// extrusion width), or as PrusaSlicer's automatic width ([`Self::auto_width`]).
    pub fn external_perimeter_width_stated(&self) -> bool {
        self.width("external_perimeter_extrusion_width")
            .or_else(|| self.width("extrusion_width"))
            .or_else(|| self.auto_width())
            .is_some()
    }

    /// PrusaSlicer's automatic external perimeter width, where the file sets it and the
    /// general width to `0` and states the nozzle: 1.125 x the nozzle (its
    /// `Flow::auto_extrusion_width`; the walls' `;WIDTH` says so). Taken from the walls as
    /// extruded instead, a 0.6 mm nozzle's plate over fins printed as single lines of
    /// 0.8-1.04 mm got loops 0.95 mm wide, too wide to bite the fins (17.7 mm in air).
    /// SuperSlicer (which writes `extrusion_spacing`) computes its own.
    fn auto_width(&self) -> Option<f64> {
        let zero = |k: &str| self.get(k).map(str::trim) == Some("0");
        let auto = zero("external_perimeter_extrusion_width")
            && self
                .get("extrusion_width")
                .is_none_or(|_| zero("extrusion_width"))
            && self.get("extrusion_spacing").is_none();
        let nozzle = self
            .number("nozzle_diameter")
            .filter(|d| (0.05..=3.0).contains(d));
        nozzle.filter(|_| auto).map(|d| 1.125 * d)
    }

    pub fn external_perimeter_width(&self) -> f64 {
        self.width("external_perimeter_extrusion_width")
            .or_else(|| self.width("extrusion_width"))
            .unwrap_or(1.125 * self.nozzle_diameter())
    }

    pub fn relative_e(&self) -> Option<bool> {
        self.bool("use_relative_e_distances")
    }

    /// Retraction in E units: the file's length of filament, as a volume where E is one.
    pub fn retract_length(&self) -> f64 {
        let mm = self.number("retract_length").unwrap_or(0.8).max(0.0);
        if self.volumetric_e() {
            mm * crate::layers::filament_area(self.filament_diameter())
        } else {
            mm
        }
    }

    /// Whether E counts cubic millimetres of material instead of millimetres of filament:
    /// PrusaSlicer's `use_volumetric_e`, Cura's UltiGCode and Marlin (Volumetric) flavours
    /// (`;FLAVOR:Marlin(Volumetric)`: read as filament, its beads came out 2.4 times too
    /// wide, a mushroom's cap got 26 loops for 58 and E for a 1.75 mm filament).
    pub fn volumetric_e(&self) -> bool {
        self.bool("use_volumetric_e") == Some(true)
            || self.get("gcode_flavor").is_some_and(|f| {
                let f = f.trim();
                f.eq_ignore_ascii_case("UltiGCode") || f.to_ascii_lowercase().contains("volumetric")
            })
    }

    /// Cross-section (mm2) that turns E into a volume of material: the filament's, or 1 where
    /// E is a volume already.
    pub fn e_area(&self) -> f64 {
        if self.volumetric_e() {
            1.0
        } else {
            crate::layers::filament_area(self.filament_diameter())
        }
    }

    /// The slowest speed the slicer slows printing to for cooling, where the file states one
    /// (PrusaSlicer and SuperSlicer `min_print_speed`, OrcaSlicer and Bambu Studio
    /// `slow_down_min_speed`, Cura `cool_min_speed`); 0 (off) states none. A file by Cura
    /// that leaves it out has Cura's default, 10 mm/s.
    pub fn cooling_min_speed(&self) -> Option<f64> {
        self.stated_cooling_min_speed()
            .or(self.cura.then_some(CURA_COOL_MIN_SPEED))
    }

    /// [`SlicerConfig::cooling_min_speed`] as the file states it.
    pub fn stated_cooling_min_speed(&self) -> Option<f64> {
        ["min_print_speed", "slow_down_min_speed", "cool_min_speed"]
            .iter()
            .find_map(|k| self.number(k).filter(|v| *v > 0.0))
    }

    /// Filament density in g/cm3.
    pub fn filament_density(&self) -> f64 {
        self.number("filament_density")
            .filter(|d| *d > 0.0)
            .unwrap_or(1.24)
    }
}

/// OrcaSlicer's and Bambu Studio's names for the PrusaSlicer settings poa reads: (PrusaSlicer,
/// Orca). An Orca file at 0 % infill (`sparse_infill_density`) was not known hollow, and its
/// widths fell back to 1.125 x the nozzle.
pub const ORCA_NAMES: &[(&str, &str)] = &[
    (
        "external_perimeter_extrusion_width",
        "outer_wall_line_width",
    ),
    ("perimeter_extrusion_width", "inner_wall_line_width"),
    ("extrusion_width", "line_width"),
    ("first_layer_extrusion_width", "initial_layer_line_width"),
    ("first_layer_height", "initial_layer_print_height"),
    ("fill_density", "sparse_infill_density"),
    ("retract_length", "retraction_length"),
    ("retract_speed", "retraction_speed"),
    ("deretract_speed", "deretraction_speed"),
    ("retract_lift", "z_hop"),
    ("retract_before_travel", "retraction_minimum_travel"),
    ("bed_shape", "printable_area"),
];

/// The slicer settings poa uses, with the values it accepts: (key, least, most, unit).
/// A value of exactly 0 is always accepted (PrusaSlicer's "auto" or "off"); widths may also be
/// percentages (of the nozzle, 5-1000 %). Anything outside is a damaged or hostile file or
/// environment, refused before any work: a 1e13 mm width would take gigabytes, a 1e300 mm
/// retraction would be written out as a 300-digit number.
pub const SLICER_RANGES: &[(&str, f64, f64, &str)] = &[
    ("filament_diameter", 0.5, 5.0, "mm"),
    ("nozzle_diameter", 0.05, 3.0, "mm"),
    ("layer_height", 0.01, 5.0, "mm"),
    ("first_layer_height", 0.01, 5.0, "mm"),
    ("external_perimeter_extrusion_width", 0.05, 10.0, "mm"),
    ("perimeter_extrusion_width", 0.05, 10.0, "mm"),
    ("extrusion_width", 0.05, 10.0, "mm"),
    ("first_layer_extrusion_width", 0.05, 10.0, "mm"),
    ("bridge_speed", 0.1, 2000.0, "mm/s"),
    ("min_print_speed", 0.1, 2000.0, "mm/s"),
    ("slow_down_min_speed", 0.1, 2000.0, "mm/s"),
    ("cool_min_speed", 0.1, 2000.0, "mm/s"),
    ("travel_speed", 0.1, 5000.0, "mm/s"),
    ("travel_speed_z", 0.1, 5000.0, "mm/s"),
    ("retract_length", 0.0, 100.0, "mm"),
    ("retract_speed", 0.1, 1000.0, "mm/s"),
    ("deretract_speed", 0.1, 1000.0, "mm/s"),
    ("retract_lift", 0.0, 50.0, "mm"),
    ("retract_before_travel", 0.0, 10000.0, "mm"),
    ("filament_density", 0.1, 30.0, "g/cm3"),
    ("machine_max_feedrate_x", 0.0, 1e5, "mm/s"),
    ("machine_max_feedrate_y", 0.0, 1e5, "mm/s"),
    ("machine_max_feedrate_z", 0.0, 1e5, "mm/s"),
    ("machine_max_feedrate_e", 0.0, 1e5, "mm/s"),
    ("machine_max_acceleration_x", 0.0, 1e7, "mm/s2"),
    ("machine_max_acceleration_y", 0.0, 1e7, "mm/s2"),
    ("machine_max_acceleration_z", 0.0, 1e7, "mm/s2"),
    ("machine_max_acceleration_e", 0.0, 1e7, "mm/s2"),
    ("machine_max_acceleration_extruding", 0.0, 1e7, "mm/s2"),
    ("machine_max_acceleration_retracting", 0.0, 1e7, "mm/s2"),
    ("machine_max_acceleration_travel", 0.0, 1e7, "mm/s2"),
    ("machine_max_jerk_x", 0.0, 1e5, "mm/s"),
    ("machine_max_jerk_y", 0.0, 1e5, "mm/s"),
    ("machine_max_jerk_z", 0.0, 1e5, "mm/s"),
    ("machine_max_jerk_e", 0.0, 1e5, "mm/s"),
    ("machine_min_extruding_rate", 0.0, 1e5, "mm/s"),
    ("machine_min_travel_rate", 0.0, 1e5, "mm/s"),
];

impl SlicerConfig {
    /// Checks every setting of [`SLICER_RANGES`] the file or environment gives (each value of
    /// a per-extruder list). A value that is not a number is left to the getters' defaults;
    /// a number out of range is an error naming the setting, its value and where it came from.
    pub fn check(&self) -> Result<(), crate::error::Error> {
        for &(key, lo, hi, unit) in SLICER_RANGES {
            let Some(v) = self.get(key) else { continue };
            for item in v.split([',', ';', '|']) {
                let item = item.trim();
                let (text, percent) = match item.strip_suffix('%') {
                    Some(p) => (p.trim(), true),
                    None => (item.trim_end_matches("mm").trim(), false),
                };
                let Ok(x) = text.parse::<f64>() else { continue };
                let (lo, hi, unit) = if percent {
                    (5.0, 1000.0, "%")
                } else {
                    (lo, hi, unit)
                };
                if x == 0.0 || (x >= lo && x <= hi) {
                    continue;
                }
                let origin = if self.is_from_env(key) {
                    format!(
                        "the environment variable SLIC3R_{}",
                        key.to_ascii_uppercase()
                    )
                } else {
                    "the file's configuration".to_string()
                };
                let key = self.named(key);
                return Err(crate::error::Error::Invalid(format!(
                    "slicer setting {key} = {item} (from {origin}) is outside {lo}-{hi} {unit}; fix it in the slicer and export again"
                )));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn orca_s_names_are_read_and_range_checked() {
        let orca = super::SlicerConfig::parse(
            b"; CONFIG_BLOCK_START\n; nozzle_diameter = 0.4\n; line_width = 0.42\n\
; outer_wall_line_width = 0\n; sparse_infill_density = 0%\n; retraction_length = 0.6\n\
; z_hop = 0.4\n; CONFIG_BLOCK_END\n",
        );
        // Orca's 0 is "the line width", as PrusaSlicer's is "the extrusion width".
        assert_eq!(orca.external_perimeter_width(), 0.42);
        assert_eq!(orca.fill_density(), Some(0.0));
        assert_eq!(orca.retract_length(), 0.6);
        assert_eq!(orca.get("retract_lift"), Some("0.4"));
        // PrusaSlicer's own name wins where both are there.
        let both =
            super::SlicerConfig::parse(b"; fill_density = 20%\n; sparse_infill_density = 0%\n");
        assert_eq!(both.fill_density(), Some(20.0));
        let absurd = super::SlicerConfig::parse(b"; outer_wall_line_width = 1e13\n");
        let e = absurd.check().unwrap_err().to_string();
        assert!(e.contains("outer_wall_line_width = 1e13"), "{e}");
    }

    #[test]
    fn cura_front_end_settings_are_read() {
        // As Cura 4.13 writes them: cut at 80 columns, the JSON's `\n` escaped once more.
        let text = concat!(
            ";FLAVOR:Marlin\n",
            ";SETTING_3 {\"global_quality\": \"[general]\\\\nversion = 4\\\\nname = Fine #2\\\\ndefinit\n",
            ";SETTING_3 ion = creality_ender3\\\\n\\\\n[values]\\\\nlayer_height = 0.12\\\\n\\\\n\", \"extrud\n",
            ";SETTING_3 er_quality\": [\"[general]\\\\nversion = 4\\\\n\\\\n[values]\\\\ninfill_sparse_dens\n",
            ";SETTING_3 ity = 0\\\\nwall_line_count = 3\\\\n\\\\n\"]}\n",
        );
        let cfg = SlicerConfig::parse(text.as_bytes());
        assert_eq!(cfg.fill_density(), Some(0.0));
        assert_eq!(cfg.number("layer_height"), Some(0.12));
        assert_eq!(cfg.number("wall_line_count"), Some(3.0));
        assert_eq!(cfg.get("gcode_flavor"), Some("Marlin"));
    }

    #[test]
    fn the_first_layer_compensation_is_read_from_every_family() {
        let ps = SlicerConfig::parse(b"; elefant_foot_compensation = 0.2\n");
        assert_eq!(ps.elephant_foot(), 0.2);
        let ss = SlicerConfig::parse(b"; first_layer_size_compensation = -0.15\n");
        assert_eq!(ss.elephant_foot(), 0.15);
        let cura = SlicerConfig::parse(
            b";SETTING_3 {\"global_quality\": \"[values]\\\\nxy_offset_layer_0 = -0.1\\\\n\"}\n",
        );
        assert_eq!(cura.elephant_foot(), 0.1);
        // Grown, not drawn in; or out of range: no spread.
        assert_eq!(
            SlicerConfig::parse(b"; first_layer_size_compensation = 0.3\n").elephant_foot(),
            0.0
        );
        assert_eq!(
            SlicerConfig::parse(b"; elefant_foot_compensation = 1e9\n").elephant_foot(),
            0.0
        );
    }

    #[test]
    fn fuzzy_skin_is_read_from_both_families() {
        let none = SlicerConfig::parse(b"; fuzzy_skin = none\n; fuzzy_skin_thickness = 0.3\n");
        assert_eq!(none.fuzzy_skin(), 0.0);
        assert_eq!(
            SlicerConfig::parse(b"; layer_height = 0.2\n").fuzzy_skin(),
            0.0
        );
        let ps = SlicerConfig::parse(b"; fuzzy_skin = external\n; fuzzy_skin_thickness = 0.5\n");
        assert_eq!(ps.fuzzy_skin(), 0.5);
        let orca = SlicerConfig::parse(b"; fuzzy_skin = allwalls\n");
        assert_eq!(orca.fuzzy_skin(), 0.3);
        let wild = SlicerConfig::parse(b"; fuzzy_skin = all\n; fuzzy_skin_thickness = 1e9\n");
        assert_eq!(wild.fuzzy_skin(), 0.3);
        let cura = SlicerConfig::parse(
            b";SETTING_3 {\"global_quality\": \"[values]\\\\nmagic_fuzzy_skin_enabled = True\\\\nmagic_f\n;SETTING_3 uzzy_skin_thickness = 0.4\\\\n\"}\n",
        );
        assert_eq!(cura.fuzzy_skin(), 0.4);
    }

    #[test]
    fn fill_density_is_read_in_percent() {
        let prusa = SlicerConfig::parse(b"; fill_density = 0%\n");
        assert_eq!(prusa.fill_density(), Some(0.0));
        let some = SlicerConfig::parse(b"; fill_density = 15%\n");
        assert_eq!(some.fill_density(), Some(15.0));
        assert_eq!(
            SlicerConfig::parse(b"; fill_density = 150%\n").fill_density(),
            None
        );
        assert_eq!(SlicerConfig::parse(b"G1 X1\n").fill_density(), None);
    }

    #[test]
    fn ultigcode_and_volumetric_e_count_e_as_a_volume() {
        let cura = SlicerConfig::parse(b";FLAVOR:UltiGCode\n;TIME:6666\n");
        assert!(cura.volumetric_e());
        assert_eq!(cura.e_area(), 1.0);
        // 0.8 mm of 1.75 mm filament is 1.92 mm3.
        assert!((cura.retract_length() - 0.8 * 2.405).abs() < 0.01);
        let prusa = SlicerConfig::parse(b"; use_volumetric_e = 1\n; retract_length = 1\n");
        assert!(prusa.volumetric_e());
        let marlin = SlicerConfig::parse(b";FLAVOR:Marlin(Volumetric)\n;TIME:6666\n");
        assert!(marlin.volumetric_e());
        assert_eq!(marlin.e_area(), 1.0);
        let plain = SlicerConfig::parse(b";FLAVOR:Marlin\n");
        assert!(!plain.volumetric_e());
        assert!((plain.e_area() - 2.405).abs() < 0.001);
        assert_eq!(plain.retract_length(), 0.8);
    }

    use super::*;

    #[test]
    fn prusaslicer_s_automatic_width_is_stated_by_the_nozzle() {
        let block = |lines: &str| {
            let text = format!("; prusaslicer_config = begin\n{lines}; prusaslicer_config = end\n");
            SlicerConfig::parse(text.as_bytes())
        };
        let auto = block(
            "; nozzle_diameter = 0.6\n; external_perimeter_extrusion_width = 0\n\
; extrusion_width = 0\n",
        );
        assert!(auto.external_perimeter_width_stated());
        assert!((auto.external_perimeter_width() - 0.675).abs() < 1e-12);
        // No nozzle stated, or SuperSlicer's spacing keys: the walls as extruded decide.
        let no_nozzle = block("; external_perimeter_extrusion_width = 0\n; extrusion_width = 0\n");
        assert!(!no_nozzle.external_perimeter_width_stated());
        let superslicer = block(
            "; nozzle_diameter = 0.4\n; external_perimeter_extrusion_width = 0\n\
; extrusion_width = 0\n; extrusion_spacing = 0\n",
        );
        assert!(!superslicer.external_perimeter_width_stated());
        // A general width stated: that one.
        let general = block(
            "; nozzle_diameter = 0.4\n; external_perimeter_extrusion_width = 0\n\
; extrusion_width = 0.5\n",
        );
        assert!(general.external_perimeter_width_stated());
        assert!((general.external_perimeter_width() - 0.5).abs() < 1e-12);
    }

    #[test]
    fn reads_prusaslicer_block_and_env_overrides() {
        let text = b"; prusaslicer_config = begin\n; filament_diameter = 2.85,1.75\n\
; nozzle_diameter = 0.6\n; external_perimeter_extrusion_width = 150%\n\
; use_relative_e_distances = 1\n; prusaslicer_config = end\n";
        let mut c = SlicerConfig::parse(text);
        assert_eq!(c.filament_diameter(), 2.85);
        assert!((c.external_perimeter_width() - 0.9).abs() < 1e-12);
        assert_eq!(c.relative_e(), Some(true));
        c.apply_env([
            ("SLIC3R_FILAMENT_DIAMETER".to_string(), "1.75".to_string()),
            ("PATH".to_string(), "/bin".to_string()),
        ]);
        assert_eq!(c.filament_diameter(), 1.75);
        assert!(c.is_from_env("filament_diameter"));
    }

    #[test]
    fn simplify3d_and_cura_headers() {
        let c = SlicerConfig::parse(b";   filamentDiameters,1.75|1.75\n;Layer height: 0.15\n");
        assert_eq!(c.layer_height(), Some(0.15));
        assert_eq!(c.filament_diameter(), 1.75);
    }

    /// Cura's Griffin header (Ultimaker S5) names the nozzle, not the filament: 2.85 mm is
    /// the only filament those printers take (1.75 made poa's loops 1.64 x too heavy).
    #[test]
    fn cura_griffin_header_means_2_85_mm_filament() {
        let head = b";START_OF_HEADER\n;FLAVOR:Griffin\n;EXTRUDER_TRAIN.0.NOZZLE.DIAMETER:0.6\n";
        let c = SlicerConfig::parse(head);
        assert_eq!(c.filament_diameter(), 2.85);
        assert_eq!(c.nozzle_diameter(), 0.6);
        let stated = SlicerConfig::parse(b";FLAVOR:Griffin\n; filament_diameter = 1.75\n");
        assert_eq!(stated.filament_diameter(), 1.75);
        let marlin = SlicerConfig::parse(b";FLAVOR:Marlin\n");
        assert_eq!(marlin.filament_diameter(), 1.75);
    }

    #[test]
    fn out_of_range_settings_are_refused_with_their_origin() {
        let c = SlicerConfig::parse(b"; external_perimeter_extrusion_width = 1e13\n");
        let e = c.check().unwrap_err().to_string();
        assert!(
            e.contains("external_perimeter_extrusion_width = 1e13"),
            "{e}"
        );
        assert!(e.contains("the file's configuration"), "{e}");
        let mut c = SlicerConfig::parse(b"; retract_length = 0.8\n; bridge_speed = 0\n");
        assert!(c.check().is_ok(), "0 is auto");
        c.apply_env([("SLIC3R_TRAVEL_SPEED_Z".to_string(), "1e-9".to_string())]);
        let e = c.check().unwrap_err().to_string();
        assert!(e.contains("SLIC3R_TRAVEL_SPEED_Z"), "{e}");
        for bad in ["1e300%", "-1", "inf", "NaN"] {
            let c = SlicerConfig::parse(format!("; extrusion_width = {bad}\n").as_bytes());
            assert!(c.check().is_err(), "{bad}");
        }
        let c =
            SlicerConfig::parse(b"; extrusion_width = 112.5%\n; filament_diameter = 1.75,2.85\n");
        assert!(c.check().is_ok());
        let c = SlicerConfig::parse(b"; filament_diameter = 1.75,1e9\n");
        assert!(c.check().is_err());
    }

    #[test]
    fn defaults_for_nonsense() {
        let c = SlicerConfig::parse(b"; filament_diameter = banana\n; nozzle_diameter = -1\n");
        assert_eq!(c.filament_diameter(), 1.75);
        assert_eq!(c.nozzle_diameter(), 0.4);
    }
}
