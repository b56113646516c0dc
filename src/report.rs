//! Last stage: what a user reads.
//!
//! Input: the stream of layers from [`crate::layers`] and regions from [`crate::geometry`].
//! Output: serialisable reports (`poa info`, `poa analyze`) with a human rendering that fits a terminal and a JSON rendering whose field
//! names are stable (documented in README.md).

use std::collections::BTreeMap;
use std::fmt;
use std::io::BufRead;

use serde::Serialize;

use geo::BoundingRect;

use crate::check::{CheckOptions, LayerCheck};
use crate::geometry::{self, DetectOptions, Region, RegionKind, RoleExtrusion, Tolerance};
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
    /// Layers printed on more than the one layer before them (objects or support material at
    /// different layer heights: their layers interleave in the file).
    pub interleaved_layers: usize,
    pub filament_diameter_mm: f64,
    /// Filament on extrusion moves inside layers (excludes start G-code priming), mm.
    pub filament_mm: f64,
    /// Filament on all extrusion moves including start G-code, mm.
    pub filament_all_mm: f64,
    pub filament_cm3: f64,
    pub filament_g: f64,
    /// The total the slicer wrote in the file's footer, when it did.
    pub stated_filament_mm: Option<f64>,
    /// poa's print-time estimate (trapezoidal motion model, the file's limits), s.
    pub estimated_time_s: f64,
    /// The slicer's own normal-mode estimate from the footer, when it wrote one, s.
    pub stated_time_s: Option<f64>,
    pub roles: Vec<RoleStats>,
    pub objects: Vec<String>,
    pub lines: u64,
    pub bytes: u64,
    pub diagnostics: Vec<DiagnosticEntry>,
}

/// The slicer's normal-mode print-time estimate from the file's statistics, s.
pub fn stated_time(config: &SlicerConfig) -> Option<f64> {
    config
        .get("estimated_printing_time")
        .and_then(crate::estimate::parse_dhms)
}

/// Reads a whole file through the pipeline and summarises it.
pub fn info<R: BufRead>(input: R, config: SlicerConfig, file: &str) -> std::io::Result<InfoReport> {
    let diameter = config.filament_diameter();
    // Filament per unit of E: 1, or per mm3 where E is a volume (UltiGCode).
    let per_e = config.e_area() / filament_area(diameter);
    let density = config.filament_density();
    let relative_cfg = config.relative_e();
    let limits = crate::estimate::Limits::from_config(&config);
    let stated_time = stated_time(&config);
    let mut reader = LayerReader::new(
        input,
        ReaderOptions {
            keep_raw: false,
            config,
        },
    )
    .with_estimate(limits);
    let mut roles: BTreeMap<Role, RoleStats> = BTreeMap::new();
    let mut layers = 0usize;
    let mut interleaved = 0usize;
    let (mut first_z, mut last_z) = (None, None);
    let (mut in_layers, mut all) = (0.0, 0.0);
    for layer in reader.by_ref() {
        let layer = layer?;
        let is_layer = layer.kind == LayerKind::Layer;
        if is_layer {
            layers += 1;
            interleaved += usize::from(layer.rests_on.len() > 1);
            first_z.get_or_insert(layer.z);
            last_z = Some(layer.z);
        }
        for p in &layer.paths {
            let e = p.e() * per_e;
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
        interleaved_layers: interleaved,
        filament_diameter_mm: diameter,
        filament_mm: in_layers,
        filament_all_mm: all,
        filament_cm3: cm3,
        filament_g: cm3 * density,
        stated_filament_mm: facts.stated_filament_mm,
        estimated_time_s: reader.estimated_time().unwrap_or(0.0),
        stated_time_s: stated_time,
        roles: roles.into_values().collect(),
        objects: reader.objects().to_vec(),
        lines: facts.lines,
        bytes: facts.bytes,
        diagnostics: diagnostics(&reader.diagnostics()),
    })
}

impl fmt::Display for InfoReport {
    /// Long by design: the report's text layout top to bottom, one section after another.
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
        if self.interleaved_layers > 0 {
            writeln!(
                f,
                "              {} layers rest on more than the layer before them (objects or support at different layer heights)",
                self.interleaved_layers
            )?;
        }
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
        write!(
            f,
            "  print time  {} (estimate)",
            crate::estimate::format_dhms(self.estimated_time_s)
        )?;
        if let Some(s) = self.stated_time_s {
            write!(f, "; the slicer says {}", crate::estimate::format_dhms(s))?;
        }
        writeln!(f)?;
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

/// One region as `poa analyze` reports it.
#[derive(Debug, Clone, Serialize)]
pub struct RegionReport {
    /// 1-based, in file order.
    pub id: usize,
    /// 1-based layer number (the first layer is 1).
    pub layer: usize,
    pub z: f64,
    pub kind: RegionKind,
    pub area_mm2: f64,
    pub max_distance_mm: f64,
    pub anchored_length_mm: f64,
    pub anchors: usize,
    pub object: Option<String>,
    /// [min x, min y, max x, max y] in mm.
    pub bbox: [f64; 4],
    /// Original extrusions inside the region, by role.
    pub extrusions: Vec<RoleExtrusion>,
    /// Sum of `extrusions`: what the slicer lays over air here.
    pub over_air_length_mm: f64,
    pub over_air_filament_mm: f64,
}

/// Totals of `poa analyze`.
#[derive(Debug, Clone, Default, Serialize)]
pub struct AnalyzeSummary {
    pub regions: usize,
    pub overhangs: usize,
    pub bridges: usize,
    pub floating: usize,
    pub layers_with_regions: usize,
    pub area_mm2: f64,
    pub over_air_length_mm: f64,
    pub over_air_filament_mm: f64,
    /// All extrusion inside layers, for scale.
    pub extruded_length_mm: f64,
}

/// The detection settings a report was made with.
#[derive(Debug, Clone, Serialize)]
pub struct DetectSettings {
    pub tolerance: Tolerance,
    /// Tolerance in mm at the file's first layer height above the first layer.
    pub tolerance_mm: f64,
    pub min_width_mm: f64,
    pub min_area_mm2: f64,
    pub external_width_mm: f64,
    /// Fuzzy skin thickness the file states (mm, 0 without): in the automatic tolerance.
    pub fuzzy_skin_mm: f64,
}

/// `poa analyze`: where the file prints over air.
#[derive(Debug, Clone, Serialize)]
pub struct AnalyzeReport {
    pub file: String,
    pub slicer: String,
    pub layers: usize,
    pub layer_source: LayerSource,
    pub settings: DetectSettings,
    pub summary: AnalyzeSummary,
    pub regions: Vec<RegionReport>,
    pub diagnostics: Vec<DiagnosticEntry>,
    /// Set when poa already rewrote the file: what the deposition check still finds in air.
    /// The regions then are the areas poa's loops print, not material over air.
    pub rewritten_by_poa: Option<StillUnsupported>,
}

/// What the deposition check finds in air in a file poa rewrote.
#[derive(Debug, Clone, Serialize)]
pub struct StillUnsupported {
    pub in_air_mm: f64,
    pub longest_in_air_mm: f64,
    /// Layer number of the longest in-air run, if any.
    pub longest_in_air_layer: Option<usize>,
    /// Layers with more than 1 mm in air.
    pub layers_in_air: usize,
}

/// If `path` holds poa's header line (its first MiB of text), runs the deposition check on
/// it; `None` for a file poa did not rewrite.
pub fn still_unsupported(path: &std::path::Path) -> crate::error::Result<Option<StillUnsupported>> {
    use std::io::Read;
    let read_err = |source| crate::error::Error::Read {
        path: path.to_path_buf(),
        source,
    };
    let mut head = Vec::new();
    crate::input::open(path)?
        .reader
        .take(1 << 20)
        .read_to_end(&mut head)
        .map_err(read_err)?;
    if !crate::emit::already_processed(&head) {
        return Ok(None);
    }
    let opened = crate::input::open(path)?;
    let c = check(
        opened.reader,
        opened.config,
        &CheckOptions::default(),
        &path.display().to_string(),
    )
    .map_err(read_err)?;
    Ok(Some(StillUnsupported {
        in_air_mm: c.in_air_mm,
        longest_in_air_mm: c.longest_in_air_mm,
        longest_in_air_layer: c.longest_in_air_at.map(|(l, _, _)| l),
        layers_in_air: c.layers.iter().filter(|l| l.in_air_mm > 1.0).count(),
    }))
}

/// The detection options a file's own settings call for.
pub fn detect_options(config: &SlicerConfig) -> DetectOptions {
    DetectOptions::for_file(config)
}

/// Reads a file through region detection and summarises what lies over air.
///
/// Long by design: gathers every section of the analysis report in one pass over the detected layers.
pub fn analyze<R: BufRead + Send>(
    input: R,
    config: SlicerConfig,
    opts: &DetectOptions,
    file: &str,
) -> std::io::Result<AnalyzeReport> {
    let mut reader = LayerReader::new(
        input,
        ReaderOptions {
            keep_raw: false,
            config,
        },
    );
    let mut regions: Vec<(Region, Option<u32>)> = Vec::new();
    let mut layers = 0usize;
    let mut extruded = 0.0;
    let mut first_height = None;
    geometry::detect(reader.by_ref(), opts, |d| {
        if d.layer.kind == LayerKind::Layer {
            layers += 1;
            extruded += d.layer.paths.iter().map(|p| p.length()).sum::<f64>();
            if d.layer.index == 1 {
                first_height = Some(d.layer.height);
            }
        }
        regions.extend(d.regions.into_iter().map(|r| {
            let o = r.object;
            (r, o)
        }));
        Ok(())
    })?;
    let objects = reader.objects().to_vec();
    let facts = reader.facts().clone();
    let mut summary = AnalyzeSummary {
        extruded_length_mm: extruded,
        ..Default::default()
    };
    let mut layer_ids = Vec::new();
    let reports: Vec<RegionReport> = regions
        .into_iter()
        .enumerate()
        .map(|(i, (r, object))| {
            let bbox = r
                .polygon
                .bounding_rect()
                .map(|b| [b.min().x, b.min().y, b.max().x, b.max().y])
                .unwrap_or([0.0; 4]);
            let len: f64 = r.extrusions.iter().map(|e| e.length_mm).sum();
            let fil: f64 = r.extrusions.iter().map(|e| e.filament_mm).sum();
            summary.regions += 1;
            match r.kind {
                RegionKind::Overhang => summary.overhangs += 1,
                RegionKind::Bridge => summary.bridges += 1,
                RegionKind::Floating => summary.floating += 1,
            }
            summary.area_mm2 += r.area;
            summary.over_air_length_mm += len;
            summary.over_air_filament_mm += fil;
            if layer_ids.last() != Some(&r.layer) {
                layer_ids.push(r.layer);
            }
            RegionReport {
                id: i + 1,
                layer: r.layer + 1,
                z: r.z,
                kind: r.kind,
                area_mm2: r.area,
                max_distance_mm: r.max_distance,
                anchored_length_mm: r.anchored_length,
                anchors: r.anchors,
                object: object.and_then(|o| objects.get(o as usize).cloned()),
                bbox,
                extrusions: r.extrusions,
                over_air_length_mm: len,
                over_air_filament_mm: fil,
            }
        })
        .collect();
    summary.layers_with_regions = layer_ids.len();
    Ok(AnalyzeReport {
        file: file.to_string(),
        slicer: facts.slicer.name().to_string(),
        layers,
        layer_source: facts.layer_source,
        settings: DetectSettings {
            tolerance: opts.tolerance,
            tolerance_mm: opts.tolerance_at(first_height.unwrap_or(0.2)),
            min_width_mm: opts.min_width(),
            min_area_mm2: opts.min_area,
            external_width_mm: opts.external_width,
            fuzzy_skin_mm: opts.fuzzy_skin,
        },
        summary,
        regions: reports,
        diagnostics: diagnostics(&reader.diagnostics()),
        rewritten_by_poa: None,
    })
}

fn diagnostics(d: &crate::machine::Diagnostics) -> Vec<DiagnosticEntry> {
    d.list()
        .into_iter()
        .map(|(line, message, count)| DiagnosticEntry {
            line,
            count,
            message,
        })
        .collect()
}

impl fmt::Display for AnalyzeReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = &self.summary;
        writeln!(f, "{} ({}, {} layers)", self.file, self.slicer, self.layers)?;
        if let Some(u) = &self.rewritten_by_poa {
            writeln!(
                f,
                "  already rewritten by poa: the regions below are where its loops print"
            )?;
            match u.longest_in_air_layer {
                Some(l) if u.in_air_mm > 0.0 => writeln!(
                    f,
                    "  still in air (deposition check): {:.1} mm on {} layer{} over 1 mm, longest run {:.1} mm on layer {l}; `poa check` shows where",
                    u.in_air_mm,
                    u.layers_in_air,
                    plural(u.layers_in_air),
                    u.longest_in_air_mm
                )?,
                _ => writeln!(f, "  still in air (deposition check): nothing")?,
            }
        }
        if s.regions == 0 {
            writeln!(f, "  no region prints over air")?;
        } else {
            writeln!(
                f,
                "  {} region{} {} on {} layer{}: {} overhang, {} bridge, {} floating",
                s.regions,
                plural(s.regions),
                if self.rewritten_by_poa.is_some() {
                    "rewritten"
                } else {
                    "over air"
                },
                s.layers_with_regions,
                plural(s.layers_with_regions),
                s.overhangs,
                s.bridges,
                s.floating
            )?;
            let share = if s.extruded_length_mm > 0.0 {
                100.0 * s.over_air_length_mm / s.extruded_length_mm
            } else {
                0.0
            };
            if self.rewritten_by_poa.is_none() {
                writeln!(
                    f,
                    "  over air: {:.0} mm of extrusion ({share:.1} % of the print), {:.1} mm of filament",
                    s.over_air_length_mm, s.over_air_filament_mm
                )?;
            }
            writeln!(f)?;
            writeln!(
                f,
                "  {:>4} {:>5} {:>7}  {:<8} {:>9} {:>8} {:>9}  object",
                "#", "layer", "Z mm", "kind", "area mm2", "reach mm", "anchor mm"
            )?;
            for r in &self.regions {
                writeln!(
                    f,
                    "  {:>4} {:>5} {:>7.2}  {:<8} {:>9.1} {:>8.1} {:>9.1}  {}",
                    r.id,
                    r.layer,
                    r.z,
                    r.kind.name(),
                    r.area_mm2,
                    r.max_distance_mm,
                    r.anchored_length_mm,
                    r.object.as_deref().unwrap_or("-")
                )?;
            }
        }
        let fuzzy = match (&self.settings.tolerance, self.settings.fuzzy_skin_mm) {
            (Tolerance::Auto, t) if t > 0.0 => {
                format!(", with the file's fuzzy skin thickness {t:.2} mm")
            }
            _ => String::new(),
        };
        writeln!(
            f,
            "  (tolerance {:.3} mm{fuzzy}, minimum width {:.2} mm, minimum area {:.1} mm2)",
            self.settings.tolerance_mm, self.settings.min_width_mm, self.settings.min_area_mm2
        )?;
        for d in &self.diagnostics {
            writeln!(f, "  note: line {}: {}", d.line, d.message)?;
        }
        Ok(())
    }
}

fn plural(n: usize) -> &'static str {
    if n == 1 {
        ""
    } else {
        "s"
    }
}

/// `poa check`: how much of each layer is laid on material that already exists.
#[derive(Debug, Clone, Serialize)]
pub struct CheckReport {
    pub file: String,
    pub options: CheckOptions,
    pub length_mm: f64,
    pub supported_mm: f64,
    pub bridged_mm: f64,
    pub in_air_mm: f64,
    pub longest_in_air_mm: f64,
    /// Layer number, [x, y] and line of the longest in-air run.
    pub longest_in_air_at: Option<(usize, [f64; 2], u64)>,
    pub filament_mm: f64,
    /// Print-time estimate (trapezoidal motion model), s.
    pub time_s: f64,
    pub layers: Vec<LayerCheck>,
}

/// Simulates the deposition of a whole file, layer by layer.
///
/// Long by design: one pass over the stream that simulates each layer, runs the time
/// estimate and gathers the totals, which all read the same lines.
pub fn check<R: BufRead + Send>(
    input: R,
    config: SlicerConfig,
    opts: &CheckOptions,
    file: &str,
) -> std::io::Result<CheckReport> {
    let fa = config.e_area();
    let limits = crate::estimate::Limits::from_config(&config);
    let mut reader = LayerReader::new(
        input,
        ReaderOptions {
            keep_raw: false,
            config,
        },
    )
    .with_estimate(limits);
    let mut rep = CheckReport {
        file: file.to_string(),
        options: opts.clone(),
        length_mm: 0.0,
        supported_mm: 0.0,
        bridged_mm: 0.0,
        in_air_mm: 0.0,
        longest_in_air_mm: 0.0,
        longest_in_air_at: None,
        filament_mm: 0.0,
        time_s: 0.0,
        layers: Vec::new(),
    };
    // Layers are checked in parallel batches; each needs the layers it rests on, so the last
    // layers of a batch are carried into the next: the last one, or as many as the farthest
    // any layer so far has rested back (objects of different layer heights interleave, or
    // support holds a layer across its contact gap, or stands on one across its own).
    const BATCH: usize = 4;
    let checks = geometry::read_ahead(reader.by_ref(), |layers| {
        let mut checks: Vec<LayerCheck> = Vec::new();
        let mut batch: Vec<crate::layers::Layer> = Vec::with_capacity(BATCH + 1);
        let mut carried = 0;
        let mut span = 1;
        loop {
            let next = layers.next().transpose()?;
            let end = next.is_none();
            if let Some(l) = next.filter(|l| l.kind == LayerKind::Layer) {
                batch.push(l);
            }
            if batch.len() < BATCH + carried && !end {
                continue;
            }
            for l in &batch[carried..] {
                let back = (l.rests_on.iter().chain(&l.contact).chain(&l.gap_below))
                    .map(|&i| l.index.saturating_sub(i));
                // Three at least: the layers under the one below hold taller infill.
                span = back
                    .fold(span.max(3), usize::max)
                    .min(crate::layers::RECENT_LAYERS);
            }
            let done: Vec<LayerCheck> = {
                use rayon::prelude::*;
                (carried..batch.len())
                    .into_par_iter()
                    .map(|i| {
                        let earlier = batch[..i].iter();
                        let below = crate::check::resting_on(&batch[i], earlier.clone());
                        // The two layers under them hold infill printed two or three times
                        // as tall as the layer.
                        let under = |v: &[&'_ crate::layers::Layer]| -> Vec<&crate::layers::Layer> {
                            v.iter()
                                .flat_map(|b| b.rests_on.iter())
                                .filter_map(|&j| earlier.clone().find(|l| l.index == j))
                                .collect()
                        };
                        let mut deeper = under(&below);
                        deeper.extend(under(&deeper));
                        crate::check::check_layer_over(&below, &deeper, &batch[i], fa, opts)
                    })
                    .collect()
            };
            checks.extend(done);
            if end {
                return Ok(checks);
            }
            batch.drain(..batch.len().saturating_sub(span));
            carried = batch.len();
        }
    })?;
    rep.time_s = reader.estimated_time().unwrap_or(0.0);
    for c in checks {
        rep.length_mm += c.length_mm;
        rep.supported_mm += c.supported_mm;
        rep.bridged_mm += c.bridged_mm;
        rep.in_air_mm += c.in_air_mm;
        rep.filament_mm += c.filament_mm;
        if c.longest_in_air_mm > rep.longest_in_air_mm {
            rep.longest_in_air_mm = c.longest_in_air_mm;
            rep.longest_in_air_at = c.longest_in_air_at.map(|(p, l)| (c.layer, p, l));
        }
        rep.layers.push(c);
    }
    Ok(rep)
}

impl fmt::Display for CheckReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let pct = |x: f64| {
            if self.length_mm > 0.0 {
                100.0 * x / self.length_mm
            } else {
                0.0
            }
        };
        writeln!(f, "{}", self.file)?;
        writeln!(
            f,
            "  extruded {:.0} mm: supported {:.2} %, bridged {:.2} %, in air {:.2} % ({:.1} mm)",
            self.length_mm,
            pct(self.supported_mm),
            pct(self.bridged_mm),
            pct(self.in_air_mm),
            self.in_air_mm
        )?;
        if let Some((layer, p, line)) = self.longest_in_air_at {
            writeln!(
                f,
                "  longest in-air run: {:.1} mm on layer {layer} at X{:.2} Y{:.2} (line {line})",
                self.longest_in_air_mm, p[0], p[1]
            )?;
        }
        writeln!(f)?;
        writeln!(
            f,
            "  {:>5} {:>7} {:>10} {:>9} {:>9} {:>9} {:>8}",
            "layer", "Z mm", "length mm", "bridged", "in air", "longest", "density"
        )?;
        for l in &self.layers {
            if l.in_air_mm < 0.05 && l.bridged_mm < 0.05 && (0.8..=1.3).contains(&l.density) {
                continue;
            }
            writeln!(
                f,
                "  {:>5} {:>7.2} {:>10.0} {:>9.1} {:>9.1} {:>9.1} {:>8.2}",
                l.layer,
                l.z,
                l.length_mm,
                l.bridged_mm,
                l.in_air_mm,
                l.longest_in_air_mm,
                l.density
            )?;
        }
        writeln!(
            f,
            "  (layers fully supported with density 0.8-1.3 not listed)"
        )?;
        Ok(())
    }
}

/// `poa check --compare`: two files side by side, and the layers that differ.
#[derive(Debug, Clone, Serialize)]
pub struct CompareReport {
    pub original: CheckReport,
    pub file: CheckReport,
    /// Filament the second file uses beyond the first (mm).
    pub filament_added_mm: f64,
    /// Print time the second file takes beyond the first (s, same estimator).
    pub time_added_s: f64,
    /// Layers whose extrusion differs: (layer, Z, before, after).
    pub changed: Vec<(usize, f64, LayerSummary, LayerSummary)>,
}

#[derive(Debug, Clone, Serialize)]
pub struct LayerSummary {
    pub length_mm: f64,
    pub supported_mm: f64,
    pub bridged_mm: f64,
    pub in_air_mm: f64,
    pub density: f64,
    pub filament_mm: f64,
}

impl From<&LayerCheck> for LayerSummary {
    fn from(l: &LayerCheck) -> Self {
        LayerSummary {
            length_mm: l.length_mm,
            supported_mm: l.supported_mm,
            bridged_mm: l.bridged_mm,
            in_air_mm: l.in_air_mm,
            density: l.density,
            filament_mm: l.filament_mm,
        }
    }
}

/// Pairs the layers of two check reports (by position) and keeps those that changed.
pub fn compare(original: CheckReport, file: CheckReport) -> CompareReport {
    let mut changed = Vec::new();
    for (a, b) in original.layers.iter().zip(&file.layers) {
        let differs = (a.length_mm - b.length_mm).abs() > 0.01
            || (a.filament_mm - b.filament_mm).abs() > 1e-4
            || (a.in_air_mm - b.in_air_mm).abs() > 0.01;
        if differs {
            changed.push((b.layer, b.z, a.into(), b.into()));
        }
    }
    CompareReport {
        filament_added_mm: file.filament_mm - original.filament_mm,
        time_added_s: file.time_s - original.time_s,
        original,
        file,
        changed,
    }
}

impl fmt::Display for CompareReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let line = |r: &CheckReport| {
            let pct = |x: f64| {
                if r.length_mm > 0.0 {
                    100.0 * x / r.length_mm
                } else {
                    0.0
                }
            };
            format!(
                "{:<40} {:>10.0} {:>9.2} % {:>8.2} % {:>9.1} {:>10.1}",
                r.file,
                r.length_mm,
                pct(r.supported_mm),
                pct(r.bridged_mm),
                r.in_air_mm,
                r.filament_mm
            )
        };
        writeln!(
            f,
            "{:<40} {:>10} {:>11} {:>10} {:>9} {:>10}",
            "file", "length mm", "supported", "bridged", "in air mm", "filament mm"
        )?;
        writeln!(f, "{}", line(&self.original))?;
        writeln!(f, "{}", line(&self.file))?;
        writeln!(f, "filament added: {:+.1} mm", self.filament_added_mm)?;
        writeln!(
            f,
            "time added: {:+.0} s ({} -> {})",
            self.time_added_s,
            crate::estimate::format_dhms(self.original.time_s),
            crate::estimate::format_dhms(self.file.time_s)
        )?;
        if self.changed.is_empty() {
            writeln!(f, "no layer differs")?;
            return Ok(());
        }
        writeln!(f)?;
        writeln!(
            f,
            "{:>5} {:>7}  {:>19} {:>19} {:>15}",
            "layer", "Z mm", "in air mm (was/now)", "bridged (was/now)", "density"
        )?;
        for (layer, z, a, b) in &self.changed {
            writeln!(
                f,
                "{:>5} {:>7.2}  {:>9.1} {:>9.1} {:>9.1} {:>9.1} {:>7.2} {:>7.2}",
                layer,
                z,
                a.in_air_mm,
                b.in_air_mm,
                a.bridged_mm,
                b.bridged_mm,
                a.density,
                b.density
            )?;
        }
        Ok(())
    }
}
