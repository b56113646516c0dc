//! The `poa` command line: parses arguments, does file I/O, maps errors to exit codes.
//! All the work happens in the `printonair` library.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

use printonair::emit::{self, ObjectFilter, ProcessOptions, ProcessReport};
use printonair::geometry::DetectOptions;
use printonair::layers::SlicerConfig;
use printonair::{input, output, preview, report, settings};

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
    /// A/B test plate: the part as sliced plus a copy shifted by DX,DY with Print-on-Air
    /// applied to the copy only, both printed in every layer, each its own object.
    Ab {
        file: PathBuf,
        /// Output file.
        #[arg(short, long, value_name = "OUT")]
        output: PathBuf,
        /// Shift of the copy in mm, e.g. --offset 60,0.
        #[arg(long, value_name = "DX,DY", allow_hyphen_values = true)]
        offset: String,
        /// Least distance between the copy and the original's material, mm.
        #[arg(long, value_name = "MM", default_value_t = 5.0)]
        gap: f64,
        /// Bed rectangle X0,Y0,X1,Y1 in mm, when the file does not state its bed shape.
        #[arg(long, value_name = "X0,Y0,X1,Y1", allow_hyphen_values = true)]
        bed: Option<String>,
        #[command(flatten)]
        rewrite: RewriteArgs,
    },
    /// Convert between binary G-code (.bgcode) and text G-code, whichever the input is.
    Convert {
        /// A .bgcode file (recognised by its content, whatever its name) or a text G-code file
        /// written by PrusaSlicer.
        input: PathBuf,
        /// The file to write: text from binary, binary from text.
        output: PathBuf,
        /// Block compression for text -> binary: `prusaslicer` (what PrusaSlicer 2.7+ writes)
        /// or `libbgcode` (libbgcode's converters: print metadata uncompressed).
        #[arg(long, value_name = "PRESET", default_value = "prusaslicer", value_parser = ["prusaslicer", "libbgcode"])]
        preset: String,
    },
    /// List the built-in settings profiles, or print one as YAML to copy and edit.
    Profiles {
        #[command(subcommand)]
        action: Option<ProfilesAction>,
    },
    /// Print the settings in force for a file and where each comes from.
    Config {
        file: PathBuf,
        /// Machine-readable output.
        #[arg(long)]
        json: bool,
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
        /// Compare with this original: both side by side, and the layers that changed.
        #[arg(long, value_name = "ORIGINAL")]
        compare: Option<PathBuf>,
        /// Also draw this layer (1 = first) with its bridged and in-air points, into -o.
        #[arg(long, value_name = "N", requires = "output")]
        svg_layer: Option<usize>,
        /// Where --svg-layer writes its SVG.
        #[arg(short, long, value_name = "OUT.svg")]
        output: Option<PathBuf>,
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

#[derive(Subcommand)]
enum ProfilesAction {
    /// Print a built-in profile as commented YAML.
    Show { name: String },
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
    /// Settings profile: a built-in name (`poa profiles` lists them) or a YAML file
    /// [default: the built-in profile matching the slicer's filament type, if any].
    #[arg(long, value_name = "NAME|PATH")]
    profile: Option<String>,
    /// Set any setting: `--set fan=80` (repeatable; `poa profiles show pla` lists the keys).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
    /// Nozzle temperature change while printing loops, degrees C.
    #[arg(long, value_name = "C", allow_hyphen_values = true)]
    temperature_offset: Option<f64>,
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
    /// Print what happened to each region.
    #[arg(short, long)]
    verbose: bool,
    /// Leave the slicer's M73 progress lines as they are (by default their remaining times
    /// and percentages are recomputed for the time the rewrite adds).
    #[arg(long)]
    keep_progress: bool,
    #[command(flatten)]
    detect: DetectArgs,
}

impl RewriteArgs {
    /// The flags as `(key, value)` pairs, in precedence order (named flags, then `--set`).
    fn flags(&self) -> anyhow::Result<Vec<(String, String)>> {
        let mut f = self.detect.flags();
        let mut num = |key: &str, v: Option<f64>| {
            if let Some(x) = v {
                f.push((key.to_string(), x.to_string()));
            }
        };
        num("overlap", self.overlap);
        num("loop_speed", self.loop_speed);
        num("perimeter_speed", self.perimeter_speed);
        num("fan", self.fan);
        num("dwell", self.dwell);
        num("flow_factor", self.flow);
        num("perimeter_inset", self.perimeter_inset);
        num("temperature_offset", self.temperature_offset);
        if let Some(b) = &self.bridges {
            f.push(("bridges".into(), b.clone()));
        }
        for kv in &self.set {
            let Some((k, v)) = kv.split_once('=') else {
                anyhow::bail!("--set takes KEY=VALUE (got {kv:?})");
            };
            f.push((k.trim().to_string(), v.trim().to_string()));
        }
        Ok(f)
    }

    fn effective(&self, config: &SlicerConfig) -> anyhow::Result<settings::Effective> {
        Ok(settings::resolve(
            self.profile.as_deref(),
            config,
            &self.flags()?,
        )?)
    }

    fn options(&self, config: &SlicerConfig) -> anyhow::Result<ProcessOptions> {
        let objects = ObjectFilter::from_globs(&self.objects, &self.skip_objects)
            .map_err(|e| anyhow::anyhow!(e))?;
        let eff = self.effective(config)?;
        let mut header = format!("{} {}:", emit::HEADER_MARK, env!("CARGO_PKG_VERSION"));
        if let Some(p) = &eff.profile {
            header.push_str(&format!(" profile {p};"));
        }
        let poa = eff.poa_settings();
        let motion = emit::Motion::from_config(config, &poa);
        header.push_str(&format!(" loops at {} mm/s;", motion.loop_speed));
        header.push(' ');
        header.push_str(&eff.summary());
        Ok(ProcessOptions {
            detect: eff.detect_options(config),
            settings: eff.poa_settings(),
            objects,
            header,
        })
    }
}

impl DetectArgs {
    fn flags(&self) -> Vec<(String, String)> {
        let mut f = Vec::new();
        for (key, v) in [
            ("tolerance", self.tolerance),
            ("overhang_angle", self.overhang_angle),
            ("min_width", self.min_width),
            ("min_area", self.min_area),
        ] {
            if let Some(x) = v {
                f.push((key.to_string(), x.to_string()));
            }
        }
        f
    }

    fn options(&self, config: &SlicerConfig) -> anyhow::Result<DetectOptions> {
        Ok(settings::resolve(None, config, &self.flags())?.detect_options(config))
    }
}

fn main() -> ExitCode {
    bound_heap();
    let cli = match parse_args() {
        Ok(cli) => cli,
        Err(code) => return code,
    };
    match run(cli) {
        Ok(code) => code,
        // A reader that stopped early (`poa analyze x | head`) is not an error.
        Err(e)
            if e.chain().any(|c| {
                c.downcast_ref::<std::io::Error>()
                    .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
            }) =>
        {
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("poa: {}", error_text(&e));
            ExitCode::from(1)
        }
    }
}

/// The error and its causes, each said once (a library error often states its cause in its
/// own message already).
fn error_text(e: &anyhow::Error) -> String {
    let mut text = String::new();
    for cause in e.chain() {
        let c = cause.to_string();
        if !text.contains(&c) {
            if !text.is_empty() {
                text.push_str(": ");
            }
            text.push_str(&c);
        }
    }
    text
}

/// Parses the command line. Usage errors get poa's prefix and fit in two lines (a slicer shows
/// them in a small dialog); a mistyped command name gets a suggestion instead of being taken
/// for the G-code file of slicer mode.
fn parse_args() -> Result<Cli, ExitCode> {
    use clap::CommandFactory;
    let args: Vec<std::ffi::OsString> = std::env::args_os().collect();
    let names: Vec<String> = Cli::command()
        .get_subcommands()
        .map(|c| c.get_name().to_string())
        .collect();
    if let Some(first) = args.get(1).and_then(|a| a.to_str()) {
        let looks_like_command = !first.starts_with('-')
            && !first.contains(['.', '/'])
            && !std::path::Path::new(first).exists()
            && !names.iter().any(|n| n == first);
        if looks_like_command {
            let best = names
                .iter()
                .map(|n| (strsim::damerau_levenshtein(first, n), n))
                .min()
                .filter(|(d, n)| *d <= 2.max(n.len() / 3));
            let hint = match best {
                Some((_, n)) => format!("did you mean `poa {n}`?"),
                None => format!("commands: {}", names.join(", ")),
            };
            eprintln!("poa: `{first}` is neither a command nor a file; {hint}");
            return Err(ExitCode::from(2));
        }
    }
    Cli::try_parse_from(&args).map_err(|e| {
        use clap::error::ErrorKind;
        if matches!(
            e.kind(),
            ErrorKind::DisplayHelp
                | ErrorKind::DisplayVersion
                | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand
        ) {
            let _ = e.print();
            return ExitCode::from(if e.use_stderr() { 2 } else { 0 });
        }
        let text = e.render().to_string();
        let mut lines = text.lines().map(str::trim).filter(|l| !l.is_empty());
        let first = lines.next().unwrap_or("bad arguments");
        let first = first.strip_prefix("error: ").unwrap_or(first);
        // "the following required arguments were not provided:" names them on the next line.
        let first = match first.strip_suffix(':') {
            Some(head) => format!("{head}: {}", lines.next().unwrap_or("")),
            None => first.to_string(),
        };
        let tip = lines
            .find(|l| l.starts_with("tip:"))
            .map(|t| format!("{t}; "))
            .unwrap_or_default();
        eprintln!(
            "poa: {first}\n  {tip}usage: poa [OPTIONS] FILE, or poa COMMAND ... (poa --help)"
        );
        ExitCode::from(2)
    })
}

fn write_stdout(text: &str) -> anyhow::Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes())?;
    out.flush()?;
    Ok(())
}

fn emit_json<T: serde::Serialize>(value: &T) -> anyhow::Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    serde_json::to_writer_pretty(&mut out, value).map_err(std::io::Error::from)?;
    writeln!(out)?;
    Ok(())
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
        Command::Ab {
            file,
            output: out,
            offset,
            gap,
            bed,
            rewrite,
        } => ab_command(&file, &out, &offset, gap, bed.as_deref(), &rewrite),
        Command::Convert {
            input,
            output: out,
            preset,
        } => {
            output::check_not_input(&out, &[&input])?;
            let data = input::read_all(&input)?;
            let bytes = if printonair::bgcode::is_bgcode(&data) {
                let decoded =
                    printonair::bgcode::decode(&data).map_err(|e| printonair::Error::NotGcode {
                        path: input.clone(),
                        reason: format!("the binary G-code is damaged: {e}"),
                    })?;
                decoded.to_ascii()
            } else {
                let mut config = printonair::bgcode::BinarizeConfig::prusaslicer();
                if preset == "libbgcode" {
                    config.print_metadata = printonair::bgcode::Compression::None;
                }
                let file = printonair::bgcode::from_ascii(&data, &config)
                    .map_err(|e| anyhow::anyhow!("{}: {e}", input.display()))?;
                printonair::bgcode::encode(&file)
            };
            output::write_bytes(&out, &[&input], &bytes)?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Profiles { action } => {
            let text = match action {
                None => {
                    let mut t =
                        String::from("built-in profiles (poa profiles show NAME prints one):\n");
                    for (name, aliases, _) in settings::BUILTIN {
                        t.push_str(&format!("  {name:<6} for {}\n", aliases.join(", ")));
                    }
                    t.push_str("without --profile, poa picks the one matching the slicer's filament type\n");
                    t
                }
                Some(ProfilesAction::Show { name }) => {
                    let Some((_, text)) = settings::builtin(&name) else {
                        anyhow::bail!("no built-in profile `{name}`; `poa profiles` lists them");
                    };
                    text.to_string()
                }
            };
            write_stdout(&text)?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Config {
            file,
            json,
            rewrite,
        } => {
            let opened = input::open(&file)?;
            let eff = rewrite.effective(&opened.config)?;
            if json {
                emit_json(&eff)?;
            } else {
                let mut t = eff.to_string();
                let c = &opened.config;
                t.push_str("from the slicer (config block, overridden by SLIC3R_* variables):\n");
                for key in [
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
                ] {
                    let v = c.get(key).unwrap_or("(not set)");
                    let src = if c.is_from_env(key) {
                        "SLIC3R_ variable"
                    } else if c.get(key).is_some() {
                        "file"
                    } else {
                        ""
                    };
                    t.push_str(&format!("  {key:<36} {v:<12} {src}\n"));
                }
                write_stdout(&t)?;
            }
            Ok(ExitCode::SUCCESS)
        }
        Command::Check {
            file,
            json,
            overlap_min,
            max_bridge,
            fail_in_air,
            compare,
            svg_layer,
            output: svg_out,
        } => {
            anyhow::ensure!(
                (0.0..0.5).contains(&overlap_min),
                "--overlap-min must be between 0 and 0.5"
            );
            anyhow::ensure!(max_bridge >= 0.0, "--max-bridge must be 0 or more");
            if let Some(out) = &svg_out {
                let mut inputs = vec![file.as_path()];
                inputs.extend(compare.as_deref());
                output::check_not_input(out, &inputs)?;
            }
            let opened = input::open(&file)?;
            let opts = printonair::check::CheckOptions {
                overlap_min,
                max_bridge,
                ..Default::default()
            };
            let name = file.display().to_string();
            let rep =
                report::check(opened.reader, opened.config, &opts, &name).map_err(|source| {
                    printonair::Error::Read {
                        path: file.clone(),
                        source,
                    }
                })?;
            let in_air = rep.in_air_mm;
            if let (Some(n), Some(out)) = (svg_layer, svg_out) {
                let again = input::open(&file)?;
                let title = file
                    .file_name()
                    .map(|f| f.to_string_lossy().to_string())
                    .unwrap_or_default();
                let svg = preview::check_layer_svg(again.reader, again.config, &opts, n, &title)
                    .map_err(|source| printonair::Error::Read {
                        path: file.clone(),
                        source,
                    })?;
                let Some(svg) = svg else {
                    anyhow::bail!("{} has no layer {n}", file.display());
                };
                let mut inputs = vec![file.as_path()];
                inputs.extend(compare.as_deref());
                write_file(&out, &inputs, &svg)?;
            }
            if let Some(orig) = compare {
                let o = input::open(&orig)?;
                let orig_name = orig.display().to_string();
                let before = report::check(o.reader, o.config, &opts, &orig_name)
                    .map_err(|source| printonair::Error::Read { path: orig, source })?;
                emit(&report::compare(before, rep), json)?;
            } else {
                emit(&rep, json)?;
            }
            if let Some(limit) = fail_in_air.filter(|limit| in_air > *limit) {
                eprintln!(
                    "poa: {} prints {in_air:.1} mm in air, more than --fail-in-air {limit} mm",
                    file.display()
                );
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
            if regions {
                check_regions_folder(&output, &file)?;
            } else {
                output::check_not_input(&output, &[&file])?;
            }
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
                    write_file(&output.join(name), &[&file], svg)?;
                }
                write_file(&output.join("index.html"), &[&file], &previews.index)?;
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
                write_file(&output, &[&file], &svg)?;
            }
            Ok(ExitCode::SUCCESS)
        }
    }
}

/// Writes an output file atomically, refusing to write over any of `inputs`.
fn write_file(
    path: &std::path::Path,
    inputs: &[&std::path::Path],
    text: &str,
) -> anyhow::Result<()> {
    output::write_bytes(path, inputs, text.as_bytes())?;
    Ok(())
}

/// Numbers separated by commas, exactly `n` of them.
fn parse_numbers(text: &str, n: usize, what: &str) -> anyhow::Result<Vec<f64>> {
    let v: Vec<f64> = text
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .ok()
        .filter(|v: &Vec<f64>| v.len() == n && v.iter().all(|x| x.is_finite()))
        .ok_or_else(|| {
            anyhow::anyhow!("{what} takes {n} numbers separated by commas, got `{text}`")
        })?;
    Ok(v)
}

fn ab_command(
    file: &std::path::Path,
    out: &std::path::Path,
    offset: &str,
    gap: f64,
    bed: Option<&str>,
    args: &RewriteArgs,
) -> anyhow::Result<ExitCode> {
    use std::io::Read;
    let d = parse_numbers(offset, 2, "--offset")?;
    output::check_not_input(out, &[file])?;
    let bed = bed
        .map(|b| parse_numbers(b, 4, "--bed").map(|v| [v[0], v[1], v[2], v[3]]))
        .transpose()?;
    let mut opened = input::open(file)?;
    if emit::already_processed(&opened.head) {
        anyhow::bail!(
            "{} was already rewritten by poa; make the A/B plate from the slicer's original",
            file.display()
        );
    }
    let mut text = Vec::new();
    opened
        .reader
        .read_to_end(&mut text)
        .map_err(|source| printonair::Error::Read {
            path: file.to_path_buf(),
            source,
        })?;
    let plate = printonair::ab::build(
        &text,
        &opened.config,
        &printonair::ab::AbOptions {
            offset: [d[0], d[1]],
            gap,
            bed,
        },
    )
    .map_err(|e| anyhow::anyhow!("cannot make an A/B plate of {}: {e}", file.display()))?;
    let mut opts = args.options(&opened.config)?;
    opts.objects =
        emit::ObjectFilter::from_globs(&plate.copy_names, &[]).map_err(|e| anyhow::anyhow!(e))?;
    let read_err = |source| printonair::Error::Read {
        path: file.to_path_buf(),
        source,
    };
    // The statistics and progress lines count the copy too.
    let totals = printonair::progress::Totals {
        normal: parse_time(opened.config.get("estimated_printing_time")),
        silent: parse_time(opened.config.get("estimated_printing_time_silent")),
    };
    let mut text = Vec::with_capacity(plate.text.len());
    printonair::progress::update(&plate.text[..], &mut text, &plate.added, totals)
        .map_err(read_err)?;
    let footer = footer_start(&text);
    let fa = printonair::layers::filament_area(opened.config.filament_diameter());
    let tail = emit::update_footer(
        &text[footer..],
        plate.added_filament_mm,
        plate.added_time_s,
        fa,
        opened.config.filament_density(),
    );
    text.truncate(footer);
    text.extend_from_slice(&tail);
    let scale = match (totals.normal, totals.silent) {
        (Some(n), Some(s)) if n > 0.0 => s / n,
        _ => 1.0,
    };
    let totals = printonair::progress::Totals {
        normal: totals.normal.map(|t| t + plate.added_time_s),
        silent: totals.silent.map(|t| t + plate.added_time_s * scale),
    };
    let mut result = Vec::new();
    let report = emit::process(&text[..], opened.config, &opts, &mut result).map_err(read_err)?;
    if needs_progress_update(&report, args) {
        let mut fixed = Vec::with_capacity(result.len());
        printonair::progress::update(&result[..], &mut fixed, &report.progress, totals)
            .map_err(read_err)?;
        result = fixed;
    }
    let bytes = match opened.binary {
        Some(mut layout) => {
            emit::update_binary_metadata(&mut layout.other, &report);
            let werr = |source| printonair::Error::Write {
                path: out.to_path_buf(),
                source,
            };
            let mut blocks =
                printonair::bgcode::stream::GcodeWriter::new(Vec::new(), &layout).map_err(werr)?;
            std::io::Write::write_all(&mut blocks, &result).map_err(werr)?;
            blocks.finish().map_err(werr)?
        }
        None => result,
    };
    output::write_bytes(out, &[file], &bytes)?;
    write_stdout(&format!(
        "{}: A/B plate with the copy `{}` shifted by {},{} mm on {} layers; {} region(s) of the copy rewritten with {} loops\n",
        out.display(),
        plate.copy_name,
        d[0],
        d[1],
        plate.layers,
        report.regions_rewritten,
        report.loops
    ))?;
    Ok(ExitCode::SUCCESS)
}

/// Start of the line where the last 64 KiB of `text` begin: the statistics footer lies there.
fn footer_start(text: &[u8]) -> usize {
    let from = text.len().saturating_sub(64 * 1024);
    if from == 0 {
        return 0;
    }
    text[from..]
        .iter()
        .position(|&b| b == b'\n')
        .map_or(text.len(), |i| from + i + 1)
}

fn parse_time(text: Option<&str>) -> Option<f64> {
    text.and_then(printonair::estimate::parse_dhms)
}

/// Whether the rewrite added time before progress lines that should show it.
fn needs_progress_update(report: &ProcessReport, args: &RewriteArgs) -> bool {
    !args.keep_progress && report.has_progress_lines && !report.progress.is_empty()
}

/// glibc raises its mmap threshold each time a large block is freed, after which the
/// megabyte-sized buffers of a big plate's layers come from the heap and their memory stays
/// with the process when freed. A fixed threshold keeps them mapped and handed back, so
/// peak memory follows what the pipeline holds, not what it once held.
fn bound_heap() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only changes allocator tunables; called before any thread starts.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 256 * 1024);
        libc::mallopt(libc::M_TRIM_THRESHOLD, 1024 * 1024);
    }
}

/// Rewrites one file into `dest` (which may be the file itself), refusing to write over any of
/// `inputs`. Returns `None` when the file was already rewritten by poa and is left as it is.
fn rewrite_file(
    file: &std::path::Path,
    dest: Option<&std::path::Path>,
    inputs: &[&std::path::Path],
    args: &RewriteArgs,
    progress: bool,
) -> anyhow::Result<Option<ProcessReport>> {
    let opened = input::open(file)?;
    if emit::already_processed(&opened.head) {
        return Ok(None);
    }
    let opts = args.options(&opened.config)?;
    let totals = printonair::progress::Totals {
        normal: parse_time(opened.config.get("estimated_printing_time")),
        silent: parse_time(opened.config.get("estimated_printing_time_silent")),
    };
    let reader = Progress::new(opened.reader, opened.size, progress);
    let read_err = |source| printonair::Error::Read {
        path: file.to_path_buf(),
        source,
    };
    // Reading and writing share the stream; say which side failed.
    let stream_err = |e: std::io::Error, dest: &std::path::Path| -> printonair::Error {
        if matches!(
            e.kind(),
            std::io::ErrorKind::Other
                | std::io::ErrorKind::InvalidData
                | std::io::ErrorKind::AlreadyExists
        ) {
            read_err(e)
        } else {
            printonair::Error::Write {
                path: dest.to_path_buf(),
                source: e,
            }
        }
    };
    let filter_err = |report: &ProcessReport| -> printonair::error::Result<()> {
        object_filter_matches(file, report, &opts.objects).map_err(printonair::Error::Invalid)
    };
    let opened_binary = opened.binary;
    if let (Some(dest), Some(_)) = (dest, &opened_binary) {
        if dest != file && dest.extension().is_none_or(|e| e != "bgcode") {
            eprintln!(
                "poa: note: {} is binary G-code, so {} is written as binary G-code too (PrusaSlicer names such files .bgcode; `poa convert` makes text)",
                file.display(),
                dest.display()
            );
        }
    }
    let result = match (dest, opened_binary) {
        (Some(dest), Some(mut layout)) => output::write_atomic_twice(
            dest,
            inputs,
            // Binary G-code: the rewritten text goes to a first temporary file, then into G-code
            // blocks after the metadata, which states the new totals.
            |w| {
                let report = emit::process(reader, opened.config, &opts, w)
                    .map_err(|e| stream_err(e, dest))?;
                filter_err(&report)?;
                Ok(report)
            },
            |_| true,
            |report, written, w| {
                emit::update_binary_metadata(&mut layout.other, report);
                let werr = |source| printonair::Error::Write {
                    path: dest.to_path_buf(),
                    source,
                };
                let mut blocks =
                    printonair::bgcode::stream::GcodeWriter::new(w, &layout).map_err(werr)?;
                if needs_progress_update(report, args) {
                    printonair::progress::update(written, &mut blocks, &report.progress, totals)
                        .map_err(werr)?;
                } else {
                    std::io::copy(&mut std::io::BufReader::new(written), &mut blocks)
                        .map_err(werr)?;
                }
                blocks.finish().map_err(werr)?;
                Ok(())
            },
        ),
        (Some(dest), None) => output::write_atomic_twice(
            dest,
            inputs,
            |w| {
                let report = emit::process(reader, opened.config, &opts, w)
                    .map_err(|e| stream_err(e, dest))?;
                filter_err(&report)?;
                Ok(report)
            },
            |report| needs_progress_update(report, args),
            // The progress lines precede the layers that added time: a second pass over the
            // written text gives them the new times.
            |report, written, w| {
                printonair::progress::update(written, w, &report.progress, totals)
                    .map(|_| ())
                    .map_err(|source| printonair::Error::Write {
                        path: dest.to_path_buf(),
                        source,
                    })
            },
        ),
        (None, _) => emit::process(reader, opened.config, &opts, &mut std::io::sink())
            .map_err(read_err)
            .and_then(|r| filter_err(&r).map(|_| r)),
    };
    let report = match result {
        Ok(r) => r,
        // poa's header line past the head of the file: rewritten before, nothing written now.
        Err(printonair::Error::Read { source, .. }) if emit::is_already_processed(&source) => {
            return Ok(None)
        }
        Err(e) => return Err(e.into()),
    };
    if args.verbose {
        let mut t = String::new();
        for s in &report.rewrites {
            t.push_str(&format!(
                "poa: region {} on layer {} (Z {:.2}): {} loops, {} strands, {:.0} mm written, {:.0} mm taken out, filament {:+.1} mm, time {:+.0} s\n",
                s.region,
                s.layer,
                s.z,
                s.loops,
                s.strands,
                s.written_length_mm,
                s.removed_length_mm,
                s.written_filament_mm - s.removed_filament_mm,
                s.time_added_s
            ));
        }
        for s in &report.skipped {
            t.push_str(&format!("poa: {}\n", skipped_line(s)));
        }
        write_stdout(&t)?;
    }
    Ok(Some(report))
}

/// `--objects` / `--skip-objects` patterns must each name an object of the file: a typo would
/// otherwise rewrite nothing (or everything) without a word.
fn object_filter_matches(
    file: &std::path::Path,
    report: &ProcessReport,
    filter: &ObjectFilter,
) -> Result<(), String> {
    let missing = filter.unmatched(&report.objects);
    if missing.is_empty() {
        return Ok(());
    }
    let objects = if report.objects.is_empty() {
        "it labels no objects".to_string()
    } else {
        format!("its objects: {}", report.objects.join(", "))
    };
    Err(format!(
        "object pattern {} matches no object of {}; {objects} (`poa info` lists them)",
        missing
            .iter()
            .map(|m| format!("`{m}`"))
            .collect::<Vec<_>>()
            .join(", "),
        file.display()
    ))
}

/// Counts what the pipeline reads and shows it as a progress bar on stderr, only when stderr
/// is a terminal (a slicer running poa sees nothing) and the file is big enough to wait for.
struct Progress<R> {
    inner: R,
    bar: Option<indicatif::ProgressBar>,
}

impl<R> Progress<R> {
    fn new(inner: R, size: u64, wanted: bool) -> Self {
        use std::io::IsTerminal;
        let show = wanted && size > 16 * 1024 * 1024 && std::io::stderr().is_terminal();
        let bar = show.then(|| {
            let bar = indicatif::ProgressBar::new(size);
            bar.set_style(
                indicatif::ProgressStyle::with_template("poa {bar:40} {bytes}/{total_bytes} {eta}")
                    .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
            );
            bar
        });
        Progress { inner, bar }
    }
}

impl<R: std::io::Read> std::io::Read for Progress<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        if let Some(b) = &self.bar {
            b.inc(n as u64);
        }
        Ok(n)
    }
}

impl<R: std::io::BufRead> std::io::BufRead for Progress<R> {
    fn fill_buf(&mut self) -> std::io::Result<&[u8]> {
        self.inner.fill_buf()
    }

    fn consume(&mut self, amt: usize) {
        if let Some(b) = &self.bar {
            b.inc(amt as u64);
        }
        self.inner.consume(amt);
    }
}

impl<R> Drop for Progress<R> {
    fn drop(&mut self) {
        if let Some(b) = &self.bar {
            b.finish_and_clear();
        }
    }
}

/// `poa [OPTIONS] FILE`: what a slicer runs. Quiet on success when a slicer runs it (it
/// captures stdout), one summary line on a terminal; one or two lines on stderr on failure,
/// with the file untouched.
fn slicer_mode(file: &std::path::Path, args: &RewriteArgs) -> anyhow::Result<ExitCode> {
    use std::io::IsTerminal;
    // A killed run's temporary files go even when there is nothing to do this time.
    output::remove_stale_temps(file);
    let report = rewrite_file(file, Some(file), &[], args, true)?;
    if std::io::stdout().is_terminal() {
        write_stdout(&summary_line(file, report.as_ref(), false))?;
    }
    Ok(ExitCode::SUCCESS)
}

/// One line saying what a rewrite did to `file`.
fn summary_line(file: &std::path::Path, report: Option<&ProcessReport>, dry_run: bool) -> String {
    let Some(r) = report else {
        return format!(
            "{}: already processed by poa; left unchanged\n",
            file.display()
        );
    };
    format!(
        "{}: {} region{} found, {} rewritten with {} loops; filament {:+.1} mm, time {:+.0} s{}\n",
        file.display(),
        r.regions_found,
        if r.regions_found == 1 { "" } else { "s" },
        r.regions_rewritten,
        r.loops,
        r.filament_added_mm,
        r.time_added_s,
        if dry_run {
            " (dry run: nothing written)"
        } else {
            ""
        }
    )
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
    let dest_of = |file: &PathBuf| -> Option<PathBuf> {
        if dry_run {
            None
        } else if let Some(o) = &output {
            Some(o.clone())
        } else {
            out_dir
                .as_ref()
                .map(|d| d.join(file.file_name().unwrap_or_default()))
        }
    };
    // Everything that could overwrite an input, or two results landing in one file, is
    // refused before any work.
    let inputs: Vec<&std::path::Path> = files.iter().map(PathBuf::as_path).collect();
    let mut taken: std::collections::HashMap<PathBuf, &PathBuf> = Default::default();
    for file in files {
        let Some(d) = dest_of(file) else { continue };
        if output::same_file(file, &d) {
            anyhow::bail!(
                "{} is the input {} itself; use slicer mode (poa FILE) to rewrite in place",
                d.display(),
                file.display()
            );
        }
        output::check_not_input(&d, &inputs)?;
        if let Some(other) = taken.insert(d.clone(), file) {
            anyhow::bail!(
                "{} and {} would both be written to {}; process them in separate runs or rename one",
                other.display(),
                file.display(),
                d.display()
            );
        }
    }
    if let Some(p) = &report_path {
        output::check_not_input(p, &inputs)?;
        anyhow::ensure!(
            !taken.keys().any(|d| d == p || output::same_file(d, p)),
            "--report {} is also a G-code output; give the report its own name",
            p.display()
        );
    }
    if let Some(dir) = out_dir.as_ref() {
        if !dry_run {
            std::fs::create_dir_all(dir).map_err(|source| printonair::Error::Write {
                path: dir.clone(),
                source,
            })?;
        }
    }
    // Every file is tried, on all cores; one bad file does not stop the others.
    let outcomes: Vec<(PathBuf, Result<Option<ProcessReport>, String>)> = {
        use rayon::prelude::*;
        files
            .par_iter()
            .map(|file| {
                let dest = dest_of(file);
                let result = (|| -> anyhow::Result<Option<ProcessReport>> {
                    let r = rewrite_file(file, dest.as_deref(), &inputs, args, files.len() == 1)?;
                    if r.is_none() {
                        if let Some(d) = &dest {
                            copy_file(file, d, &inputs)?;
                        }
                    }
                    Ok(r)
                })();
                (file.clone(), result.map_err(|e| error_text(&e)))
            })
            .collect()
    };
    let mut reports = Vec::new();
    let mut failed = 0;
    let mut text = String::new();
    if files.len() > 1 {
        text.push_str(&format!(
            "{:<40} {:<12} {:>7} {:>9} {:>6} {:>8} {:>11}  status\n",
            "file", "slicer", "regions", "rewritten", "loops", "time s", "filament mm"
        ));
    }
    for (file, result) in &outcomes {
        match result {
            Ok(Some(r)) if files.len() > 1 => {
                text.push_str(&format!(
                    "{:<40} {:<12} {:>7} {:>9} {:>6} {:>+8.0} {:>+11.1}  {}\n",
                    file.display(),
                    r.slicer,
                    r.regions_found,
                    r.regions_rewritten,
                    r.loops,
                    r.time_added_s,
                    r.filament_added_mm,
                    if dry_run { "dry run" } else { "ok" }
                ));
            }
            Ok(r) => {
                text.push_str(&summary_line(file, r.as_ref(), dry_run));
                if let (Some(r), false) = (r, args.verbose) {
                    const SHOWN: usize = 20;
                    for s in r.skipped.iter().take(SHOWN) {
                        text.push_str(&format!("  {}\n", skipped_line(s)));
                    }
                    if r.skipped.len() > SHOWN {
                        text.push_str(&format!(
                            "  ... and {} more regions left as sliced (-v lists them all)\n",
                            r.skipped.len() - SHOWN
                        ));
                    }
                }
            }
            Err(e) => {
                failed += 1;
                if files.len() > 1 {
                    text.push_str(&format!("{:<40} {e}\n", file.display()));
                } else {
                    eprintln!("poa: {e}");
                }
            }
        }
        match result {
            Ok(Some(r)) => reports.push(serde_json::json!({"file": file, "report": r})),
            Ok(None) => reports.push(serde_json::json!({"file": file, "already_processed": true})),
            Err(e) => reports.push(serde_json::json!({"file": file, "error": e})),
        }
    }
    write_stdout(&text)?;
    if let Some(p) = report_path {
        let text = serde_json::to_string_pretty(&serde_json::json!({ "files": reports }))?;
        write_file(&p, &inputs, &text)?;
    }
    Ok(if failed > 0 {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    })
}

/// Copies `file` to `dest` as it is (a file poa rewrote before), atomically.
fn copy_file(
    file: &std::path::Path,
    dest: &std::path::Path,
    inputs: &[&std::path::Path],
) -> anyhow::Result<()> {
    let mut src = std::fs::File::open(file).map_err(|source| printonair::Error::Read {
        path: file.to_path_buf(),
        source,
    })?;
    output::write_atomic(dest, inputs, |w| {
        std::io::copy(&mut src, w)
            .map(|_| ())
            .map_err(|source| printonair::Error::Write {
                path: dest.to_path_buf(),
                source,
            })
    })?;
    Ok(())
}

/// `preview --regions -o DIR` writes a folder: refuse a path that is a file, or that names
/// one (`r.svg`), instead of making a folder of that name.
fn check_regions_folder(dir: &std::path::Path, input: &std::path::Path) -> anyhow::Result<()> {
    output::check_not_input(dir, &[input])?;
    let looks_like_file = dir
        .extension()
        .is_some_and(|e| ["svg", "html", "htm", "gcode"].contains(&e.to_string_lossy().as_ref()));
    anyhow::ensure!(
        (!dir.exists() || dir.is_dir()) && !looks_like_file,
        "--regions writes a folder of SVG files and an index.html; -o {} is a file name (use --layer N -o FILE.svg for one layer)",
        dir.display()
    );
    Ok(())
}

fn skipped_line(s: &emit::SkippedRegion) -> String {
    format!(
        "region {} (layer {}, {}) left as sliced: {}",
        s.region,
        s.layer,
        s.kind.name(),
        s.reason
    )
}
