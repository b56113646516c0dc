//! The `poa` command line: parses arguments, calls the `printonair` library, prints, and maps
//! errors to exit codes (0 done, 1 refused or failed with a message on stderr, 2 a usage error
//! or `check --fail-in-air`). All the work happens in the library.

mod args;
mod commands;
mod print;

use std::path::Path;
use std::process::ExitCode;

use printonair::{input, report, rewrite, settings};

use args::{Cli, Command, ProfilesAction, RewriteArgs};
use print::{emit, emit_json, error_text, summary_line, write_stdout};

fn main() -> ExitCode {
    bound_heap();
    printonair::output::remove_temps_on_signals();
    printonair::geometry::quiet_polygon_panics();
    let cli = match args::parse_args() {
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

fn run(cli: Cli) -> anyhow::Result<ExitCode> {
    let Some(command) = cli.command else {
        let Some(file) = cli.file else {
            anyhow::bail!("no G-code file given; usage: poa [OPTIONS] FILE, or poa --help");
        };
        return slicer_mode(&file, &cli.rewrite);
    };
    let read_err = |path: &Path| {
        let path = path.to_path_buf();
        move |source| printonair::Error::Read { path, source }
    };
    match command {
        Command::Process {
            files,
            output,
            out_dir,
            dry_run,
            report,
            rewrite,
        } => commands::process(&files, output, out_dir, dry_run, report, &rewrite),
        Command::Info { file, json } => {
            let opened = input::open(&file)?;
            let name = file.display().to_string();
            let rep = report::info(opened.reader, opened.config, &name).map_err(read_err(&file))?;
            emit(&rep, json)?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Analyze { file, json, detect } => {
            let opened = input::open(&file)?;
            let opts = detect.options(&opened.config)?;
            let name = file.display().to_string();
            let mut rep = report::analyze(opened.reader, opened.config, &opts, &name)
                .map_err(read_err(&file))?;
            rep.rewritten_by_poa = report::still_unsupported(&file)?;
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
        } => {
            let d = parse_numbers(&offset, 2, "--offset")?;
            let bed = bed
                .map(|b| parse_numbers(&b, 4, "--bed").map(|v| [v[0], v[1], v[2], v[3]]))
                .transpose()?;
            let ab = printonair::ab::AbOptions {
                offset: [d[0], d[1]],
                gap,
                bed,
            };
            let done = rewrite::ab_plate(&file, &out, &ab, &rewrite.request()?)?;
            write_stdout(&format!(
                "{}: A/B plate with the copy `{}` shifted by {},{} mm on {} layers; {} region(s) of the copy rewritten with {} loops\n",
                out.display(),
                done.copy_name,
                d[0],
                d[1],
                done.layers,
                done.report.regions_rewritten,
                done.report.loops
            ))?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Convert {
            input,
            output: out,
            preset,
        } => {
            rewrite::convert_file(&input, &out, preset == "libbgcode")?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Profiles { action } => {
            let text = match action {
                None => settings::profiles_text(),
                Some(ProfilesAction::Show { name }) => {
                    let Some(text) = settings::builtin_annotated(&name) else {
                        anyhow::bail!("no built-in profile `{name}`; `poa profiles` lists them");
                    };
                    text
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
            let eff = rewrite.request()?.effective(&opened.config)?;
            if json {
                emit_json(&eff)?;
            } else {
                write_stdout(&settings::describe(&eff, &opened.config))?;
            }
            Ok(ExitCode::SUCCESS)
        }
        Command::Check(args) => commands::check(args),
        Command::Deform(args) => commands::deform(args),
        Command::Texture(args) => commands::texture(args),
        Command::Machines { name } => commands::machines(name.as_deref()),
        Command::FiveAxis(args) => commands::five_axis(args),
        Command::Sweep(args) => commands::sweep(args),
        Command::Preview {
            file,
            compare: Some(original),
            output,
            ..
        } => commands::preview_compare(&original, &file, &output),
        Command::Preview {
            file,
            layer,
            regions,
            output,
            detect,
            ..
        } => commands::preview(file, layer, regions, output, detect),
    }
}

/// `poa [OPTIONS] FILE`: what a slicer runs. Quiet on success when a slicer runs it (it
/// captures stdout), one summary line on a terminal; one or two lines on stderr on failure,
/// with the file untouched.
fn slicer_mode(file: &Path, args: &RewriteArgs) -> anyhow::Result<ExitCode> {
    use std::io::IsTerminal;
    // A killed run's temporary files go even when there is nothing to do this time.
    printonair::output::remove_stale_temps(file);
    let req = args.request()?;
    let report = commands::rewrite_one(file, Some(file), &[], args, &req, true)?;
    if std::io::stdout().is_terminal() {
        write_stdout(&summary_line(file, report.as_ref(), false))?;
    }
    Ok(ExitCode::SUCCESS)
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
