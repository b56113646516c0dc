//! The `poa` command line: parses arguments, does file I/O, maps errors to exit codes.
//! All the work happens in the `printonair` library.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

use printonair::{input, report};

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
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("poa: {e:#}");
            ExitCode::from(1)
        }
    }
}

fn run(cli: Cli) -> anyhow::Result<ExitCode> {
    match cli.command {
        Command::Info { file, json } => {
            let opened = input::open(&file)?;
            let name = file.display().to_string();
            let rep = report::info(opened.reader, opened.config, &name)
                .map_err(|source| printonair::Error::Read { path: file, source })?;
            if json {
                println!("{}", serde_json::to_string_pretty(&rep)?);
            } else {
                print!("{rep}");
            }
            Ok(ExitCode::SUCCESS)
        }
    }
}
