//! Last stage: what a user reads.
//!
//! Input: the stream of [`Layer`]s from [`crate::layers`]. Output: serialisable reports
//! (`poa info`) with a human rendering that fits a terminal and a JSON rendering whose field
//! names are stable (documented in README.md).

use std::collections::BTreeMap;
use std::fmt;
use std::io::BufRead;

use serde::Serialize;

use crate::layers::{
    filament_area, LayerKind, LayerReader, LayerSource, ReaderOptions, Role, SlicerConfig,
};

/// Extrusion totals for one role.
#[derive(Debug, Clone, Default, Serialize)]
pub struct RoleStats {
    pub role: &'static str,
    pub paths: u64,
    /// XY length of the extrusions, mm.
    pub length_mm: f64,
    /// Filament pushed, mm.
    pub filament_mm: f64,
}

#[derive(Debug, Clone, Serialize)]
pub struct DiagnosticEntry {
    pub line: u64,
    pub count: u64,
    pub message: String,
}

/// `poa info`: what the file is and what it prints.
#[derive(Debug, Clone, Serialize)]
pub struct InfoReport {
    pub file: String,
    pub slicer: String,
    pub slicer_version: String,
    /// "relative", "absolute" or both, as set by M82/M83 (or the config when neither appears).
    pub e_modes: Vec<&'static str>,
    pub layer_source: LayerSource,
    pub layers: usize,
    pub first_layer_z: Option<f64>,
    pub last_layer_z: Option<f64>,
    pub spiral_vase: bool,
    pub filament_diameter_mm: f64,
    /// Filament on extrusion moves inside layers (excludes start G-code priming), mm.
    pub filament_mm: f64,
    /// Filament on all extrusion moves including start G-code, mm.
    pub filament_all_mm: f64,
    pub filament_cm3: f64,
    pub filament_g: f64,
    /// The total the slicer wrote in the file's footer, when it did.
    pub stated_filament_mm: Option<f64>,
    pub roles: Vec<RoleStats>,
    pub objects: Vec<String>,
    pub lines: u64,
    pub bytes: u64,
    pub diagnostics: Vec<DiagnosticEntry>,
}

/// Reads a whole file through the pipeline and summarises it.
pub fn info<R: BufRead>(input: R, config: SlicerConfig, file: &str) -> std::io::Result<InfoReport> {
    let diameter = config.filament_diameter();
    let density = config.filament_density();
    let relative_cfg = config.relative_e();
    let mut reader = LayerReader::new(
        input,
        ReaderOptions {
            keep_raw: false,
            config,
        },
    );
    let mut roles: BTreeMap<Role, RoleStats> = BTreeMap::new();
    let mut layers = 0usize;
    let (mut first_z, mut last_z) = (None, None);
    let (mut in_layers, mut all) = (0.0, 0.0);
    for layer in reader.by_ref() {
        let layer = layer?;
        let is_layer = layer.kind == LayerKind::Layer;
        if is_layer {
            layers += 1;
            first_z.get_or_insert(layer.z);
            last_z = Some(layer.z);
        }
        for p in &layer.paths {
            let e = p.e();
            all += e;
            if is_layer {
                in_layers += e;
            }
            let s = roles.entry(p.role).or_default();
            s.role = p.role.name();
            s.paths += 1;
            s.length_mm += p.length();
            s.filament_mm += e;
        }
    }
    let facts = reader.facts().clone();
    let m = reader.machine();
    let mut e_modes = Vec::new();
    if m.e_modes.relative || (!m.e_modes.absolute && relative_cfg == Some(true)) {
        e_modes.push("relative");
    }
    if m.e_modes.absolute || (!m.e_modes.relative && relative_cfg != Some(true)) {
        e_modes.push("absolute");
    }
    let cm3 = in_layers * filament_area(diameter) / 1000.0;
    Ok(InfoReport {
        file: file.to_string(),
        slicer: facts.slicer.name().to_string(),
        slicer_version: facts.slicer_version.clone(),
        e_modes,
        layer_source: facts.layer_source,
        layers,
        first_layer_z: first_z,
        last_layer_z: last_z,
        spiral_vase: facts.spiral_vase,
        filament_diameter_mm: diameter,
        filament_mm: in_layers,
        filament_all_mm: all,
        filament_cm3: cm3,
        filament_g: cm3 * density,
        stated_filament_mm: facts.stated_filament_mm,
        roles: roles.into_values().collect(),
        objects: reader.objects().to_vec(),
        lines: facts.lines,
        bytes: facts.bytes,
        diagnostics: reader
            .diagnostics()
            .list()
            .into_iter()
            .map(|(line, message, count)| DiagnosticEntry {
                line,
                count,
                message,
            })
            .collect(),
    })
}

impl fmt::Display for InfoReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "{}", self.file)?;
        let version = if self.slicer_version.is_empty() {
            String::new()
        } else {
            format!(" {}", self.slicer_version)
        };
        writeln!(f, "  slicer      {}{}", self.slicer, version)?;
        writeln!(f, "  E mode      {}", self.e_modes.join(" + "))?;
        let source = match self.layer_source {
            LayerSource::Markers => "from the slicer's layer markers",
            _ => "inferred from Z",
        };
        write!(f, "  layers      {} ({source})", self.layers)?;
        if let (Some(a), Some(b)) = (self.first_layer_z, self.last_layer_z) {
            write!(f, ", Z {a:.3} .. {b:.3} mm")?;
        }
        writeln!(
            f,
            "{}",
            if self.spiral_vase {
                ", spiral vase"
            } else {
                ""
            }
        )?;
        write!(
            f,
            "  filament    {:.1} mm ({:.2} cm3, {:.1} g)",
            self.filament_mm, self.filament_cm3, self.filament_g
        )?;
        if let Some(s) = self.stated_filament_mm {
            write!(f, "; the slicer says {s:.1} mm")?;
        }
        writeln!(f)?;
        if self.filament_all_mm - self.filament_mm > 0.05 {
            writeln!(
                f,
                "              + {:.1} mm in start G-code",
                self.filament_all_mm - self.filament_mm
            )?;
        }
        writeln!(f, "  {} lines, {} bytes", self.lines, self.bytes)?;
        if !self.roles.is_empty() {
            writeln!(f)?;
            writeln!(
                f,
                "  {:<20} {:>7} {:>12} {:>13}",
                "role", "paths", "length mm", "filament mm"
            )?;
            for r in &self.roles {
                writeln!(
                    f,
                    "  {:<20} {:>7} {:>12.1} {:>13.1}",
                    r.role, r.paths, r.length_mm, r.filament_mm
                )?;
            }
        }
        if !self.objects.is_empty() {
            writeln!(f)?;
            writeln!(f, "  objects")?;
            for o in &self.objects {
                writeln!(f, "    {o}")?;
            }
        }
        if !self.diagnostics.is_empty() {
            writeln!(f)?;
            writeln!(f, "  notes")?;
            for d in &self.diagnostics {
                let times = if d.count > 1 {
                    format!(" ({} times)", d.count)
                } else {
                    String::new()
                };
                writeln!(f, "    line {}: {}{times}", d.line, d.message)?;
            }
        }
        Ok(())
    }
}
