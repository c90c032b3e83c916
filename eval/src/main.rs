//! `coppertag`: make tags, render datasets, detect, run and evaluate
//! detectors, write reports.
//!
//! Errors reach the user as one line on stderr and exit code 2 (bad input or
//! a failed step); `--help` on every subcommand explains each flag.

mod cli;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// CopperTag toolkit: occlusion-resilient fiducial markers, their detector,
/// synthetic datasets and a benchmark against AprilTag 3, ArUco 3 and STag.
#[derive(Parser)]
#[command(name = "coppertag", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Make print-ready tags: SVG at a physical size, PNG, or a sheet of many.
    Generate(cli::generate::GenerateArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match &cli.command {
        Command::Generate(args) => cli::generate::run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // One line: the chain of causes joined, as a user reads it.
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
    }
}
