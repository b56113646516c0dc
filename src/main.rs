//! The `poa` command line: parses arguments, does file I/O, maps errors to exit codes.
//! All the work happens in the `printonair` library.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

use printonair::geometry::{DetectOptions, Tolerance};
use printonair::layers::SlicerConfig;
use printonair::{input, preview, report};

#[derive(Parser)]
#[command(
    name = "poa",
    version,
    about = "Print overhangs on air: rewrite a slicer's G-code so overhangs print without supports"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
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
#[derive(clap::Args)]
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
    #[arg(long, value_name = "MM2", default_value_t = 1.0)]
    min_area: f64,
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
        anyhow::ensure!(
            self.min_area.is_finite() && self.min_area >= 0.0,
            "--min-area must be 0 or more"
        );
        o.min_area = self.min_area;
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
    match cli.command {
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
