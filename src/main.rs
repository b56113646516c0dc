//! The `poa` command line: parses arguments, does file I/O, maps errors to exit codes.
//! All the work happens in the `printonair` library.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

use printonair::emit::{self, ObjectFilter, ProcessOptions, ProcessReport};
use printonair::geometry::{DetectOptions, Tolerance};
use printonair::layers::SlicerConfig;
use printonair::poa::{BridgeMode, PoaSettings};
use printonair::{input, output, preview, report};

#[derive(Parser)]
#[command(
    name = "poa",
    version,
    about = "Print overhangs on air: rewrite a slicer's G-code so overhangs print without supports"
)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    /// Slicer mode: rewrite FILE in place (how PrusaSlicer, SuperSlicer and OrcaSlicer call
    /// post-processing scripts: the G-code path comes last).
    #[arg(value_name = "FILE", required = true)]
    file: Option<PathBuf>,
    #[command(flatten)]
    rewrite: RewriteArgs,
}

#[derive(Subcommand)]
#[allow(clippy::large_enum_variant)] // parsed once per run
enum Command {
    /// Describe a G-code file: slicer, E mode, layers, filament per role, objects, notes.
    Info {
        file: PathBuf,
        /// Machine-readable output.
        #[arg(long)]
        json: bool,
    },
    /// Find the regions that would print over air: overhangs and bridges, layer by layer.
    Analyze {
        file: PathBuf,
        /// Machine-readable output (fields documented in README.md).
        #[arg(long)]
        json: bool,
        #[command(flatten)]
        detect: DetectArgs,
    },
    /// Rewrite the regions over air with Print-on-Air loops: IN -o OUT, or IN... --out-dir DIR.
    Process {
        #[arg(required = true, value_name = "IN")]
        files: Vec<PathBuf>,
        /// Output file (one input).
        #[arg(short, long, value_name = "OUT", conflicts_with = "out_dir")]
        output: Option<PathBuf>,
        /// Output folder (any number of inputs; same file names).
        #[arg(long, value_name = "DIR")]
        out_dir: Option<PathBuf>,
        /// Show what would change; write nothing.
        #[arg(long)]
        dry_run: bool,
        /// Write per-region statistics (loops, length, filament and time added) as JSON.
        #[arg(long, value_name = "FILE.json")]
        report: Option<PathBuf>,
        #[command(flatten)]
        rewrite: RewriteArgs,
    },
    /// Simulate the deposition: how much of each layer rests on material already there.
    Check {
        file: PathBuf,
        /// Machine-readable output.
        #[arg(long)]
        json: bool,
        /// A point is supported when material lies within (0.5 - this) x its width.
        #[arg(long, value_name = "SHARE", default_value_t = 0.25)]
        overlap_min: f64,
        /// Longest unsupported span counted as an intended bridge, mm.
        #[arg(long, value_name = "MM", default_value_t = 10.0)]
        max_bridge: f64,
        /// Exit with status 2 when more than this many mm are printed in air.
        #[arg(long, value_name = "MM")]
        fail_in_air: Option<f64>,
    },
    /// Draw layers as SVG: the layer below, the strands by role, the regions over air.
    #[command(group(clap::ArgGroup::new("what").required(true).args(["layer", "regions"])))]
    Preview {
        file: PathBuf,
        /// Draw this layer (1 = first layer) into the SVG file given with -o.
        #[arg(long, value_name = "N")]
        layer: Option<usize>,
        /// Draw every layer that has regions into the folder given with -o, with an index.html.
        #[arg(long)]
        regions: bool,
        /// Output: an .svg file with --layer, a folder with --regions.
        #[arg(short, long, value_name = "PATH")]
        output: PathBuf,
        #[command(flatten)]
        detect: DetectArgs,
    },
}

/// Region detection settings shared by the commands that detect regions.
#[derive(clap::Args, Default)]
struct DetectArgs {
    /// How far (mm) a point may lie from the layer below and still count as supported
    /// [default: half the external perimeter width].
    #[arg(long, value_name = "MM", conflicts_with = "overhang_angle")]
    tolerance: Option<f64>,
    /// The same as an overhang angle from vertical: tolerance = layer height x tan(angle).
    #[arg(long, value_name = "DEG")]
    overhang_angle: Option<f64>,
    /// Narrowest region reported (mm) [default: the external perimeter width].
    #[arg(long, value_name = "MM")]
    min_width: Option<f64>,
    /// Smallest region reported (mm2).
    #[arg(long, value_name = "MM2")]
    min_area: Option<f64>,
}

/// Rewrite settings shared by slicer mode and `poa process`.
#[derive(clap::Args, Default)]
struct RewriteArgs {
    /// Rewrite bridges too (`poa`), or leave them as sliced (`keep`, the default).
    #[arg(long, value_name = "MODE", value_parser = ["keep", "poa"])]
    bridges: Option<String>,
    /// Overlap of each loop on the previous one, as a share of the bead width.
    #[arg(long, value_name = "0..0.9")]
    overlap: Option<f64>,
    /// Loop speed in mm/s [default: the file's bridge speed].
    #[arg(long, value_name = "MM/S")]
    loop_speed: Option<f64>,
    /// Speed of the region's external perimeter in mm/s [default: the loop speed].
    #[arg(long, value_name = "MM/S")]
    perimeter_speed: Option<f64>,
    /// Part-cooling fan during loops, percent.
    #[arg(long, value_name = "PERCENT")]
    fan: Option<f64>,
    /// Pause after each loop, seconds.
    #[arg(long, value_name = "S")]
    dwell: Option<f64>,
    /// Extrusion multiplier for the strands poa writes.
    #[arg(long, value_name = "FACTOR")]
    flow: Option<f64>,
    /// How far the region's external perimeter is pulled inward, mm.
    #[arg(long, value_name = "MM")]
    perimeter_inset: Option<f64>,
    /// Rewrite only these objects (comma-separated names as the file labels them; * and ?).
    #[arg(long, value_name = "NAMES", value_delimiter = ',')]
    objects: Vec<String>,
    /// Leave these objects as sliced.
    #[arg(long, value_name = "NAMES", value_delimiter = ',')]
    skip_objects: Vec<String>,
    #[command(flatten)]
    detect: DetectArgs,
}

impl RewriteArgs {
    fn options(&self, config: &SlicerConfig) -> anyhow::Result<ProcessOptions> {
        let mut s = PoaSettings::default();
        let range = |name: &str, v: Option<f64>, lo: f64, hi: f64| -> anyhow::Result<Option<f64>> {
            match v {
                Some(x) if !(x.is_finite() && x >= lo && x <= hi) => {
                    anyhow::bail!("--{name} must be between {lo} and {hi} (got {x})")
                }
                other => Ok(other),
            }
        };
        if let Some(b) = &self.bridges {
            s.bridges = if b == "poa" {
                BridgeMode::Poa
            } else {
                BridgeMode::Keep
            };
        }
        if let Some(v) = range("overlap", self.overlap, 0.05, 0.9)? {
            s.overlap = v;
        }
        s.loop_speed = range("loop-speed", self.loop_speed, 0.5, 500.0)?;
        s.perimeter_speed = range("perimeter-speed", self.perimeter_speed, 0.5, 500.0)?;
        if let Some(v) = range("fan", self.fan, 0.0, 100.0)? {
            s.fan = v / 100.0;
        }
        if let Some(v) = range("dwell", self.dwell, 0.0, 60.0)? {
            s.dwell = v;
        }
        if let Some(v) = range("flow", self.flow, 0.5, 2.0)? {
            s.flow_factor = v;
        }
        if let Some(v) = range("perimeter-inset", self.perimeter_inset, 0.0, 2.0)? {
            s.perimeter_inset = v;
        }
        let objects = ObjectFilter::from_globs(&self.objects, &self.skip_objects)
            .map_err(|e| anyhow::anyhow!(e))?;
        let detect = self.detect.options(config)?;
        let motion_speed = s
            .loop_speed
            .or_else(|| config.number("bridge_speed"))
            .unwrap_or(25.0);
        let header = format!(
            "{} {}: overlap {}, loop speed {} mm/s, fan {}%, dwell {} s, flow {}, perimeter inset {} mm, bridges {}",
            emit::HEADER_MARK,
            env!("CARGO_PKG_VERSION"),
            s.overlap,
            motion_speed,
            (s.fan * 100.0).round(),
            s.dwell,
            s.flow_factor,
            s.perimeter_inset,
            if s.bridges == BridgeMode::Poa { "poa" } else { "keep" }
        );
        Ok(ProcessOptions {
            detect,
            settings: s,
            objects,
            header,
        })
    }
}

impl DetectArgs {
    fn options(&self, config: &SlicerConfig) -> anyhow::Result<DetectOptions> {
        let mut o = report::detect_options(config);
        if let Some(t) = self.tolerance {
            anyhow::ensure!(
                t.is_finite() && (0.0..=10.0).contains(&t),
                "--tolerance must be between 0 and 10 mm"
            );
            o.tolerance = Tolerance::Distance(t);
        }
        if let Some(a) = self.overhang_angle {
            anyhow::ensure!(
                a.is_finite() && (0.0..90.0).contains(&a),
                "--overhang-angle must be between 0 and 90 degrees"
            );
            o.tolerance = Tolerance::Angle(a);
        }
        if let Some(w) = self.min_width {
            anyhow::ensure!(
                w.is_finite() && (0.0..=50.0).contains(&w),
                "--min-width must be between 0 and 50 mm"
            );
            o.min_width = Some(w);
        }
        if let Some(a) = self.min_area {
            anyhow::ensure!(a.is_finite() && a >= 0.0, "--min-area must be 0 or more");
            o.min_area = a;
        }
        Ok(o)
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(code) => code,
        // A reader that stopped early (`poa analyze x | head`) is not an error.
        Err(e)
            if e.downcast_ref::<std::io::Error>()
                .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe) =>
        {
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("poa: {e:#}");
            ExitCode::from(1)
        }
    }
}

/// Writes a report to stdout, as text or JSON.
fn emit<T: serde::Serialize + std::fmt::Display>(report: &T, json: bool) -> anyhow::Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    if json {
        serde_json::to_writer_pretty(&mut out, report).map_err(std::io::Error::from)?;
        writeln!(out)?;
    } else {
        write!(out, "{report}")?;
    }
    out.flush()?;
    Ok(())
}

fn run(cli: Cli) -> anyhow::Result<ExitCode> {
    let Some(command) = cli.command else {
        let Some(file) = cli.file else {
            anyhow::bail!("no G-code file given; usage: poa [OPTIONS] FILE, or poa --help");
        };
        return slicer_mode(&file, &cli.rewrite);
    };
    match command {
        Command::Process {
            files,
            output,
            out_dir,
            dry_run,
            report,
            rewrite,
        } => process_command(&files, output, out_dir, dry_run, report, &rewrite),
        Command::Info { file, json } => {
            let opened = input::open(&file)?;
            let name = file.display().to_string();
            let rep = report::info(opened.reader, opened.config, &name)
                .map_err(|source| printonair::Error::Read { path: file, source })?;
            emit(&rep, json)?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Analyze { file, json, detect } => {
            let opened = input::open(&file)?;
            let opts = detect.options(&opened.config)?;
            let name = file.display().to_string();
            let rep = report::analyze(opened.reader, opened.config, &opts, &name)
                .map_err(|source| printonair::Error::Read { path: file, source })?;
            emit(&rep, json)?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Check {
            file,
            json,
            overlap_min,
            max_bridge,
            fail_in_air,
        } => {
            anyhow::ensure!(
                (0.0..0.5).contains(&overlap_min),
                "--overlap-min must be between 0 and 0.5"
            );
            anyhow::ensure!(max_bridge >= 0.0, "--max-bridge must be 0 or more");
            let opened = input::open(&file)?;
            let opts = printonair::check::CheckOptions {
                overlap_min,
                max_bridge,
                ..Default::default()
            };
            let name = file.display().to_string();
            let rep = report::check(opened.reader, opened.config, &opts, &name)
                .map_err(|source| printonair::Error::Read { path: file, source })?;
            emit(&rep, json)?;
            if fail_in_air.is_some_and(|limit| rep.in_air_mm > limit) {
                return Ok(ExitCode::from(2));
            }
            Ok(ExitCode::SUCCESS)
        }
        Command::Preview {
            file,
            layer,
            regions,
            output,
            detect,
        } => {
            let opened = input::open(&file)?;
            let opts = detect.options(&opened.config)?;
            let title = file
                .file_name()
                .map(|n| n.to_string_lossy().to_string())
                .unwrap_or_default();
            let read_err = |source| printonair::Error::Read {
                path: file.clone(),
                source,
            };
            if regions {
                let previews =
                    preview::preview_regions(opened.reader, opened.config, &opts, &title)
                        .map_err(read_err)?;
                std::fs::create_dir_all(&output).map_err(|source| printonair::Error::Write {
                    path: output.clone(),
                    source,
                })?;
                for (name, svg) in &previews.layers {
                    write_file(&output.join(name), svg)?;
                }
                write_file(&output.join("index.html"), &previews.index)?;
                eprintln!(
                    "poa: {} layer{} with regions drawn; open {}",
                    previews.layers.len(),
                    if previews.layers.len() == 1 { "" } else { "s" },
                    output.join("index.html").display()
                );
            } else if let Some(n) = layer {
                let svg = preview::preview_layer(opened.reader, opened.config, &opts, n, &title)
                    .map_err(read_err)?;
                let Some(svg) = svg else {
                    anyhow::bail!(
                        "{} has no layer {n}; `poa info` shows how many it has",
                        file.display()
                    );
                };
                write_file(&output, &svg)?;
            }
            Ok(ExitCode::SUCCESS)
        }
    }
}

fn write_file(path: &std::path::Path, text: &str) -> anyhow::Result<()> {
    std::fs::write(path, text).map_err(|source| printonair::Error::Write {
        path: path.to_path_buf(),
        source,
    })?;
    Ok(())
}

/// Rewrites one file into `dest` (which may be the file itself). Returns `None` when the file
/// was already rewritten by poa and is left as it is.
fn rewrite_file(
    file: &std::path::Path,
    dest: Option<&std::path::Path>,
    args: &RewriteArgs,
) -> anyhow::Result<Option<ProcessReport>> {
    let opened = input::open(file)?;
    if emit::already_processed(&opened.head) {
        return Ok(None);
    }
    let opts = args.options(&opened.config)?;
    let read_err = |source| printonair::Error::Read {
        path: file.to_path_buf(),
        source,
    };
    let report = match dest {
        Some(dest) => output::write_atomic(dest, |w| {
            emit::process(opened.reader, opened.config, &opts, w).map_err(|e| {
                // Reading and writing share the stream; say which side failed.
                if e.kind() == std::io::ErrorKind::Other {
                    read_err(e)
                } else {
                    printonair::Error::Write {
                        path: dest.to_path_buf(),
                        source: e,
                    }
                }
            })
        })?,
        None => emit::process(opened.reader, opened.config, &opts, &mut std::io::sink())
            .map_err(read_err)?,
    };
    Ok(Some(report))
}

/// `poa [OPTIONS] FILE`: what a slicer runs. Quiet on success (the slicer shows stdout only in
/// its log); one or two lines on stderr on failure, with the file untouched.
fn slicer_mode(file: &std::path::Path, args: &RewriteArgs) -> anyhow::Result<ExitCode> {
    rewrite_file(file, Some(file), args)?;
    Ok(ExitCode::SUCCESS)
}

fn process_command(
    files: &[PathBuf],
    output: Option<PathBuf>,
    out_dir: Option<PathBuf>,
    dry_run: bool,
    report_path: Option<PathBuf>,
    args: &RewriteArgs,
) -> anyhow::Result<ExitCode> {
    if files.len() > 1 && out_dir.is_none() && !dry_run {
        anyhow::bail!("several inputs need --out-dir DIR (or --dry-run)");
    }
    if output.is_none() && out_dir.is_none() && !dry_run {
        anyhow::bail!("say where to write: -o OUT, --out-dir DIR, or --dry-run");
    }
    let mut reports = Vec::new();
    let mut failed = 0;
    for file in files {
        let dest = if dry_run {
            None
        } else if let Some(o) = &output {
            Some(o.clone())
        } else {
            out_dir
                .as_ref()
                .map(|d| d.join(file.file_name().unwrap_or_default()))
        };
        if let Some(d) = &dest {
            if same_file(file, d) {
                anyhow::bail!(
                    "{} is the input itself; use slicer mode (poa FILE) to rewrite in place",
                    d.display()
                );
            }
            if let Some(dir) = out_dir.as_ref() {
                std::fs::create_dir_all(dir).map_err(|source| printonair::Error::Write {
                    path: dir.clone(),
                    source,
                })?;
            }
        }
        match rewrite_file(file, dest.as_deref(), args) {
            Ok(Some(r)) => {
                println!(
                    "{}: {} region{} found, {} rewritten with {} loops; filament {:+.1} mm, time {:+.0} s{}",
                    file.display(),
                    r.regions_found,
                    if r.regions_found == 1 { "" } else { "s" },
                    r.regions_rewritten,
                    r.loops,
                    r.filament_added_mm,
                    r.time_added_s,
                    if dry_run { " (dry run: nothing written)" } else { "" }
                );
                for s in &r.skipped {
                    println!(
                        "  region {} (layer {}, {}): left as sliced: {}",
                        s.region,
                        s.layer,
                        s.kind.name(),
                        s.reason
                    );
                }
                if !dry_run && r.regions_rewritten == 0 {
                    if let Some(d) = &dest {
                        println!(
                            "  {} is a copy of the input with poa's header line",
                            d.display()
                        );
                    }
                }
                reports.push(serde_json::json!({"file": file, "report": r}));
            }
            Ok(None) => {
                println!(
                    "{}: already processed by poa; left unchanged",
                    file.display()
                );
                if let Some(d) = &dest {
                    std::fs::copy(file, d).map_err(|source| printonair::Error::Write {
                        path: d.clone(),
                        source,
                    })?;
                }
            }
            Err(e) => {
                failed += 1;
                eprintln!("poa: {e:#}");
                reports.push(serde_json::json!({"file": file, "error": format!("{e:#}")}));
            }
        }
    }
    if let Some(p) = report_path {
        let text = serde_json::to_string_pretty(&serde_json::json!({ "files": reports }))?;
        write_file(&p, &text)?;
    }
    Ok(if failed > 0 {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    })
}

fn same_file(a: &std::path::Path, b: &std::path::Path) -> bool {
    match (std::fs::canonicalize(a), std::fs::canonicalize(b)) {
        (Ok(x), Ok(y)) => x == y,
        _ => false,
    }
}
