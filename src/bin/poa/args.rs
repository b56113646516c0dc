//! The command line: clap's view of the arguments, and what they ask of the library (a
//! [`printonair::rewrite::Request`], detection options). Only validation happens here.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

use printonair::geometry::DetectOptions;
use printonair::layers::SlicerConfig;
use printonair::rewrite::Request;
use printonair::settings;

#[derive(Parser)]
#[command(
    name = "poa",
    version,
    about = "Print overhangs on air: rewrite a slicer's G-code so overhangs print without supports"
)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Option<Command>,
    /// Slicer mode: rewrite FILE in place (how PrusaSlicer, SuperSlicer and OrcaSlicer call
    /// post-processing scripts: the G-code path comes last).
    #[arg(value_name = "FILE", required = true)]
    pub file: Option<PathBuf>,
    #[command(flatten)]
    pub rewrite: RewriteArgs,
}

#[derive(Subcommand)]
#[allow(clippy::large_enum_variant)] // parsed once per run
pub enum Command {
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
    Check(CheckArgs),
    /// Layer-less helical printing: deform a spiral-vase print into a dish, vase, sphere or
    /// your own shape (expressions), checked for printability before it is written.
    Deform(DeformArgs),
    /// List the built-in five-axis machines, or print one as YAML to copy and edit.
    Machines {
        /// A built-in machine to print.
        name: Option<String>,
    },
    /// Five-axis printing: a workpiece path with tool directions into joint G-code for a
    /// table-tilting printer.
    #[command(name = "five-axis")]
    FiveAxis(FiveAxisArgs),
    /// Slice a swept part (a section carried along a curve) into layers normal to the curve,
    /// one continuous path; joint G-code too with --machine.
    Sweep(SweepArgs),
    /// Surface texture by speed modulation at constant extrusion: slower where the picture
    /// is dark (a thicker bead), faster where it is light.
    Texture(TextureArgs),
    /// Draw layers as SVG (the layer below, the strands by role, the regions over air), or a
    /// layer-less print whole (side profile and top view, unsupported points red).
    #[command(group(clap::ArgGroup::new("what").args(["layer", "regions", "compare"])))]
    Preview {
        file: PathBuf,
        /// Compare with ORIGINAL: one HTML page in the folder given with -o, a layer slider
        /// showing both files' layers side by side wherever they differ (and the layer above),
        /// in-air points marked.
        #[arg(long, value_name = "ORIGINAL")]
        compare: Option<PathBuf>,
        /// Draw this layer (1 = first layer) into the SVG file given with -o.
        #[arg(long, value_name = "N")]
        layer: Option<usize>,
        /// Draw every layer that has regions into the folder given with -o, with an index.html.
        #[arg(long)]
        regions: bool,
        /// Output: an .svg file with --layer, a folder with --regions or --compare. A layer-less (helical)
        /// print is drawn whole: its side profile into an .svg, or a folder with the side
        /// profile, the top view and an index.html.
        #[arg(short, long, value_name = "PATH")]
        output: PathBuf,
        #[command(flatten)]
        detect: DetectArgs,
    },
}

/// `poa check`'s flags.
#[derive(clap::Args)]
pub struct CheckArgs {
    pub file: PathBuf,
    /// Machine-readable output.
    #[arg(long)]
    pub json: bool,
    /// A point is supported when material lies within (0.5 - this) x its width.
    #[arg(long, value_name = "SHARE", default_value_t = 0.25)]
    pub overlap_min: f64,
    /// Longest unsupported span counted as an intended bridge, mm.
    #[arg(long, value_name = "MM", default_value_t = 10.0)]
    pub max_bridge: f64,
    /// Exit with status 2 when more than this many mm are printed in air.
    #[arg(long, value_name = "MM")]
    pub fail_in_air: Option<f64>,
    /// Compare with this original: both side by side, and the layers that changed.
    #[arg(long, value_name = "ORIGINAL")]
    pub compare: Option<PathBuf>,
    /// Also draw this layer (1 = first) with its bridged and in-air points, into -o.
    #[arg(long, value_name = "N", requires = "output")]
    pub svg_layer: Option<usize>,
    /// Where --svg-layer writes its SVG.
    #[arg(short, long, value_name = "OUT.svg")]
    pub output: Option<PathBuf>,
    /// The file is five-axis joint G-code for this machine: replay it in the workpiece
    /// frame and judge every point against earlier material.
    #[arg(long, value_name = "M.yaml|NAME")]
    pub machine: Option<String>,
    /// Bead width and layer step of a five-axis file (with --machine), mm.
    #[arg(long, value_name = "MM", default_value_t = 0.45, requires = "machine")]
    pub width: f64,
    #[arg(
        long = "layer-height",
        value_name = "MM",
        default_value_t = 0.2,
        requires = "machine"
    )]
    pub layer_height: f64,
}

#[derive(Subcommand)]
pub enum ProfilesAction {
    /// Print a built-in profile as commented YAML.
    Show { name: String },
}

/// Region detection settings shared by the commands that detect regions.
#[derive(clap::Args, Default)]
pub struct DetectArgs {
    #[arg(long, value_name = "MM", conflicts_with = "overhang_angle", help = settings::flag_help("tolerance"))]
    pub tolerance: Option<f64>,
    #[arg(long, value_name = "DEG", help = settings::flag_help("overhang_angle"))]
    pub overhang_angle: Option<f64>,
    #[arg(long, value_name = "MM", help = settings::flag_help("min_width"))]
    pub min_width: Option<f64>,
    #[arg(long, value_name = "MM2", help = settings::flag_help("min_area"))]
    pub min_area: Option<f64>,
}

/// Rewrite settings shared by slicer mode and `poa process`.
#[derive(clap::Args, Default)]
pub struct RewriteArgs {
    /// Settings profile: a built-in name (`poa profiles` lists them) or a YAML file
    /// [default: the built-in profile matching the slicer's filament type, if any].
    #[arg(long, value_name = "NAME|PATH")]
    pub profile: Option<String>,
    /// Set any setting: `--set fan=80` (repeatable; `poa profiles show pla` lists the keys).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    #[arg(long, value_name = "C", allow_hyphen_values = true, help = settings::flag_help("temperature_offset"))]
    pub temperature_offset: Option<f64>,
    #[arg(long, value_name = "MODE", value_parser = ["auto", "keep", "poa"], help = settings::flag_help("bridges"))]
    pub bridges: Option<String>,
    #[arg(long, value_name = "SHARE", help = settings::flag_help("overlap"))]
    pub overlap: Option<f64>,
    #[arg(long, value_name = "MM/S", help = settings::flag_help("loop_speed"))]
    pub loop_speed: Option<f64>,
    #[arg(long, value_name = "MM/S", help = settings::flag_help("perimeter_speed"))]
    pub perimeter_speed: Option<f64>,
    #[arg(long, value_name = "PERCENT", help = settings::flag_help("fan"))]
    pub fan: Option<f64>,
    #[arg(long, value_name = "S", help = settings::flag_help("dwell"))]
    pub dwell: Option<f64>,
    #[arg(long, value_name = "S", help = settings::flag_help("min_loop_time"))]
    pub min_loop_time: Option<f64>,
    #[arg(long, value_name = "MM/S", help = settings::flag_help("min_loop_speed"))]
    pub min_loop_speed: Option<f64>,
    #[arg(long, value_name = "FACTOR", help = settings::flag_help("flow_factor"))]
    pub flow: Option<f64>,
    #[arg(long, value_name = "MM", help = settings::flag_help("perimeter_inset"))]
    pub perimeter_inset: Option<f64>,
    /// Rewrite only these objects (comma-separated names as the file labels them; * and ?).
    #[arg(long, value_name = "NAMES", value_delimiter = ',')]
    pub objects: Vec<String>,
    /// Leave these objects as sliced.
    #[arg(long, value_name = "NAMES", value_delimiter = ',')]
    pub skip_objects: Vec<String>,
    /// Print what happened to each region.
    #[arg(short, long)]
    pub verbose: bool,
    /// Leave the slicer's M73 progress lines as they are (by default their remaining times
    /// and percentages are recomputed for the time the rewrite adds).
    #[arg(long)]
    pub keep_progress: bool,
    #[command(flatten)]
    pub detect: DetectArgs,
    #[command(flatten)]
    pub texture: TextureFlags,
}

/// A texture applied after the Print-on-Air rewrite, in the same run (slicer mode and
/// `process`): `poa texture`'s options under `--texture-*` names.
#[derive(clap::Args, Default)]
pub struct TextureFlags {
    /// Texture the walls too: a pattern (stripes, checker, noise, text:ABC) or a PNG picture.
    #[arg(long, value_name = "PATTERN|PIC.png")]
    pub texture: Option<String>,
    /// How the texture is laid on the part (see `poa texture --help`).
    #[arg(
        long,
        value_name = "MAPPING",
        default_value = "cylindrical",
        requires = "texture"
    )]
    pub texture_mapping: String,
    /// Size of one tile of the texture, `W,H` mm.
    #[arg(long, value_name = "W,H", requires = "texture")]
    pub texture_size: Option<String>,
    /// Head speed for the darkest and the lightest texel, `LOW,HIGH` mm/s.
    #[arg(
        long,
        value_name = "LOW,HIGH",
        default_value = "15,40",
        requires = "texture"
    )]
    pub texture_speed_range: String,
    /// Roles to texture, comma-separated.
    #[arg(
        long,
        value_name = "ROLES",
        default_value = "external-perimeter",
        requires = "texture"
    )]
    pub texture_roles: String,
    /// Light = slow.
    #[arg(long, requires = "texture")]
    pub texture_invert: bool,
    /// constant (E per second kept) or velocity (E per mm kept).
    #[arg(long, value_name = "MODE", default_value = "constant", value_parser = ["constant", "velocity"], requires = "texture")]
    pub texture_mode: String,
}

impl TextureFlags {
    /// The texture asked for, if any.
    pub fn spec(&self) -> anyhow::Result<Option<printonair::texture::Spec>> {
        let Some(what) = &self.texture else {
            return Ok(None);
        };
        let is_picture = what.to_ascii_lowercase().ends_with(".png");
        let (image, pattern) = if is_picture {
            (Some(std::path::Path::new(what)), None)
        } else {
            (None, Some(what.as_str()))
        };
        texture_spec(TextureParts {
            image,
            pattern,
            mapping: &self.texture_mapping,
            size: self.texture_size.as_deref(),
            offset: None,
            speed_range: &self.texture_speed_range,
            roles: &self.texture_roles,
            invert: self.texture_invert,
            mode: &self.texture_mode,
            max_flow: None,
            center: None,
        })
        .map(Some)
    }
}

/// The texture options as given, before they are checked.
pub struct TextureParts<'a> {
    pub image: Option<&'a std::path::Path>,
    pub pattern: Option<&'a str>,
    pub mapping: &'a str,
    pub size: Option<&'a str>,
    pub offset: Option<&'a str>,
    pub speed_range: &'a str,
    pub roles: &'a str,
    pub invert: bool,
    pub mode: &'a str,
    pub max_flow: Option<f64>,
    pub center: Option<&'a str>,
}

/// Checks texture options and reads the picture: the one place `poa texture` and the
/// `--texture-*` flags become a [`printonair::texture::Spec`].
pub fn texture_spec(t: TextureParts<'_>) -> anyhow::Result<printonair::texture::Spec> {
    use printonair::texture::{self, Mapping, Mode, Source};
    let source = match (t.image, t.pattern) {
        (Some(path), None) => {
            let meta = std::fs::metadata(path)
                .map_err(|e| anyhow::anyhow!("--image {}: {e}", path.display()))?;
            anyhow::ensure!(
                meta.is_file() && meta.len() <= 64 * 1024 * 1024,
                "--image {}: not a PNG file of at most 64 MiB",
                path.display()
            );
            let data = std::fs::read(path)
                .map_err(|e| anyhow::anyhow!("--image {}: {e}", path.display()))?;
            Source::png(&data)?
        }
        (None, Some(p)) => Source::pattern(p)?,
        _ => anyhow::bail!("give one of --image, --pattern"),
    };
    let pair = |text: Option<&str>, what: &str| -> anyhow::Result<Option<[f64; 2]>> {
        text.map(|s| crate::parse_numbers(s, 2, what).map(|v| [v[0], v[1]]))
            .transpose()
    };
    let speeds = crate::parse_numbers(t.speed_range, 2, "--speed-range")?;
    if let Some(f) = t.max_flow {
        anyhow::ensure!(
            f.is_finite() && (0.1..=200.0).contains(&f),
            "--max-flow {f}: between 0.1 and 200 mm3/s"
        );
    }
    Ok(texture::Spec {
        source,
        mapping: Mapping::parse(t.mapping)?,
        size: pair(t.size, "--size")?,
        offset: pair(t.offset, "--offset")?.unwrap_or([0.0, 0.0]),
        speeds: [speeds[0], speeds[1]],
        roles: texture::parse_roles(t.roles)?,
        invert: t.invert,
        mode: if t.mode == "velocity" {
            Mode::Velocity
        } else {
            Mode::Constant
        },
        max_flow: t.max_flow,
        center: pair(t.center, "--center")?,
    })
}

impl TextureArgs {
    pub fn spec(&self) -> anyhow::Result<printonair::texture::Spec> {
        texture_spec(TextureParts {
            image: self.image.as_deref(),
            pattern: self.pattern.as_deref(),
            mapping: &self.mapping,
            size: self.size.as_deref(),
            offset: self.offset.as_deref(),
            speed_range: &self.speed_range,
            roles: &self.roles,
            invert: self.invert,
            mode: &self.mode,
            max_flow: self.max_flow,
            center: self.center.as_deref(),
        })
    }
}

impl RewriteArgs {
    /// What these flags ask of a rewrite.
    pub fn request(&self) -> anyhow::Result<Request> {
        let mut flags = self.detect.flags();
        let mut num = |key: &str, v: Option<f64>| {
            if let Some(x) = v {
                flags.push((key.to_string(), x.to_string()));
            }
        };
        num("overlap", self.overlap);
        num("loop_speed", self.loop_speed);
        num("perimeter_speed", self.perimeter_speed);
        num("fan", self.fan);
        num("dwell", self.dwell);
        num("min_loop_time", self.min_loop_time);
        num("min_loop_speed", self.min_loop_speed);
        num("flow_factor", self.flow);
        num("perimeter_inset", self.perimeter_inset);
        num("temperature_offset", self.temperature_offset);
        if let Some(b) = &self.bridges {
            flags.push(("bridges".into(), b.clone()));
        }
        for kv in &self.set {
            let Some((k, v)) = kv.split_once('=') else {
                anyhow::bail!("--set takes KEY=VALUE (got {kv:?})");
            };
            flags.push((k.trim().to_string(), v.trim().to_string()));
        }
        Ok(Request {
            profile: self.profile.clone(),
            flags,
            objects: self.objects.clone(),
            skip_objects: self.skip_objects.clone(),
            keep_progress: self.keep_progress,
            texture: self.texture.spec()?,
        })
    }
}

impl DetectArgs {
    pub fn flags(&self) -> Vec<(String, String)> {
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

    pub fn options(&self, config: &SlicerConfig) -> anyhow::Result<DetectOptions> {
        Ok(settings::resolve(None, config, &self.flags())?.detect_options(config))
    }
}
/// Parses the command line. Usage errors get poa's prefix and fit in two lines (a slicer shows
/// them in a small dialog); a mistyped command name gets a suggestion instead of being taken
/// for the G-code file of slicer mode.
pub fn parse_args() -> Result<Cli, ExitCode> {
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

/// `poa deform`'s flags.
#[derive(clap::Args)]
#[command(group(clap::ArgGroup::new("shape").required(true).args(["preset", "cylindrical", "cartesian"])))]
pub struct DeformArgs {
    /// A spiral-vase G-code file (PrusaSlicer --spiral-vase, Cura spiralize, ...).
    #[arg(value_name = "IN")]
    pub file: PathBuf,
    /// Output file.
    #[arg(short, long, value_name = "OUT")]
    pub output: PathBuf,
    /// A built-in deformation: dish, vase or sphere (see README for their formulas).
    #[arg(long, value_name = "NAME", value_parser = ["dish", "vase", "sphere"])]
    pub preset: Option<String>,
    /// A named parameter of the preset or of your expressions: `k=1.2` (repeatable).
    #[arg(long = "param", value_name = "K=V")]
    pub params: Vec<String>,
    /// Cylindrical mapping `R;THETA;Z` over x, y, z, r, theta (radians) and parameters.
    #[arg(long, value_name = "'R;THETA;Z'")]
    pub cylindrical: Option<String>,
    /// Cartesian mapping `X;Y;Z` over x, y, z, r, theta and parameters.
    #[arg(long, value_name = "'X;Y;Z'")]
    pub cartesian: Option<String>,
    /// Output cross-section (mm2) from c (input cross-section) and the point; default: c.
    #[arg(long, value_name = "EXPR")]
    pub cross_section: Option<String>,
    /// Output speed (mm/s) from v (input speed) and the point; default: v.
    #[arg(long, value_name = "EXPR")]
    pub speed: Option<String>,
    /// Centre of the coordinates, `X,Y` (default: the helix's own axis).
    #[arg(long, value_name = "X,Y")]
    pub center: Option<String>,
    /// Largest distance of the written path from the mapping, mm.
    #[arg(long, value_name = "MM", default_value_t = 0.01)]
    pub chord: f64,
    /// Write the file even when the printability check fails (with a warning).
    #[arg(long)]
    pub force: bool,
    /// Write an HTML page with the side profile and top view into this folder.
    #[arg(long, value_name = "DIR")]
    pub preview: Option<PathBuf>,
    /// Machine-readable summary.
    #[arg(long)]
    pub json: bool,
}

/// `poa texture`'s flags.
#[derive(clap::Args)]
#[command(group(clap::ArgGroup::new("picture").required(true).args(["image", "pattern"])))]
pub struct TextureArgs {
    /// A G-code file (any slicer that labels its external perimeters).
    #[arg(value_name = "IN")]
    pub file: PathBuf,
    /// Output file.
    #[arg(short, long, value_name = "OUT")]
    pub output: PathBuf,
    /// A PNG picture: dark = slow (thick bead), light = fast.
    #[arg(long, value_name = "PIC.png")]
    pub image: Option<PathBuf>,
    /// A built-in pattern: stripes, checker, noise, or text:ABC.
    #[arg(long, value_name = "NAME")]
    pub pattern: Option<String>,
    /// How the picture is laid on the part: cylindrical, planar-x, planar-y, spherical, wrap.
    #[arg(long, value_name = "MAPPING", default_value = "cylindrical")]
    pub mapping: String,
    /// Size of one tile of the picture on the surface, `W,H` mm (default: 20 mm high).
    #[arg(long, value_name = "W,H")]
    pub size: Option<String>,
    /// Where the tile starts, `U,V` mm on the surface.
    #[arg(long, value_name = "U,V")]
    pub offset: Option<String>,
    /// Head speed for the darkest and the lightest texel, `LOW,HIGH` mm/s.
    #[arg(long, value_name = "LOW,HIGH", default_value = "15,40")]
    pub speed_range: String,
    /// Roles to texture, comma-separated (external-perimeter, perimeter, ...).
    #[arg(long, value_name = "ROLES", default_value = "external-perimeter")]
    pub roles: String,
    /// Light = slow instead of dark = slow.
    #[arg(long)]
    pub invert: bool,
    /// constant (E per second kept: the paper) or velocity (E per mm kept, only F changes).
    #[arg(long, value_name = "MODE", default_value = "constant", value_parser = ["constant", "velocity"])]
    pub mode: String,
    /// Volumetric flow cap in velocity mode, mm3/s (default: the profile's, else 15).
    #[arg(long, value_name = "MM3/S")]
    pub max_flow: Option<f64>,
    /// Centre of the cylindrical and spherical mappings, `X,Y` (default: the walls' own).
    #[arg(long, value_name = "X,Y")]
    pub center: Option<String>,
    /// Write an HTML page with the picture and the predicted bead width into this folder.
    #[arg(long, value_name = "DIR")]
    pub preview: Option<PathBuf>,
    /// Machine-readable summary.
    #[arg(long)]
    pub json: bool,
}

/// How F is written for five-axis moves.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum FeedArg {
    /// F so that the tip moves at --speed.
    Tip,
    /// G93 inverse time: F = 1 / minutes of each move.
    InverseTime,
}

/// Options shared by `five-axis` and `sweep --machine`.
#[derive(clap::Args)]
pub struct JointArgs {
    /// Tip speed along the workpiece, mm/s.
    #[arg(long, value_name = "MM/S", default_value_t = 20.0)]
    pub speed: f64,
    /// How F is written.
    #[arg(long, value_enum, default_value = "tip")]
    pub feed: FeedArg,
    /// Largest distance of the tip's path from the straight workpiece segment, mm.
    #[arg(long, value_name = "MM", default_value_t = 0.01)]
    pub tolerance: f64,
}

/// `poa five-axis`'s flags.
#[derive(clap::Args)]
pub struct FiveAxisArgs {
    /// Workpiece path: G-code with `; NORMAL i j k` comments, or a CSV of x,y,z,i,j,k,e.
    #[arg(value_name = "IN")]
    pub file: PathBuf,
    #[arg(short, long, value_name = "OUT")]
    pub output: PathBuf,
    /// A machine file (YAML) or a built-in name (`poa machines`).
    #[arg(long, value_name = "M.yaml|NAME")]
    pub machine: String,
    #[command(flatten)]
    pub joints: JointArgs,
}

/// `poa sweep`'s flags.
#[derive(clap::Args)]
#[command(group(clap::ArgGroup::new("line").required(true).args(["curve", "preset"])))]
pub struct SweepArgs {
    /// The structural line: a CSV of x,y,z points (mm), starting at the bed going up.
    #[arg(long, value_name = "CURVE.csv")]
    pub curve: Option<PathBuf>,
    /// A built-in line: arc:R,ANGLE or s-curve:R,ANGLE (mm, degrees).
    #[arg(long, value_name = "SHAPE")]
    pub preset: Option<String>,
    /// The cross-section: circle:D or rect:W,H (mm).
    #[arg(long, value_name = "SHAPE")]
    pub section: String,
    #[arg(short, long, value_name = "OUT")]
    pub output: PathBuf,
    /// Bead width, mm.
    #[arg(long, value_name = "MM", default_value_t = 0.45)]
    pub width: f64,
    /// Layer step measured on the line, mm.
    #[arg(long = "layer-height", value_name = "MM", default_value_t = 0.2)]
    pub layer_height: f64,
    /// Filament diameter, mm.
    #[arg(long, value_name = "MM", default_value_t = 1.75)]
    pub filament: f64,
    /// Where the line starts on the bed, `X,Y` mm.
    #[arg(long, value_name = "X,Y", default_value = "125,105")]
    pub at: String,
    /// Write joint G-code for this machine instead of the workpiece path.
    #[arg(long, value_name = "M.yaml|NAME")]
    pub machine: Option<String>,
    /// Also write the swept part as an STL (to slice it the three-axis way and compare).
    #[arg(long, value_name = "PART.stl")]
    pub stl: Option<PathBuf>,
    /// Write an HTML page with the path in 3D and, with --machine, the joints against time.
    #[arg(long, value_name = "DIR")]
    pub preview: Option<PathBuf>,
    #[command(flatten)]
    pub joints: JointArgs,
}

impl JointArgs {
    pub fn convert(&self) -> printonair::fiveaxis::Convert {
        printonair::fiveaxis::Convert {
            speed: self.speed,
            feed: match self.feed {
                FeedArg::Tip => printonair::fiveaxis::Feed::Tip,
                FeedArg::InverseTime => printonair::fiveaxis::Feed::InverseTime,
            },
            tolerance: self.tolerance,
        }
    }
}
