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
    /// Find CopperTags in images: ids, corners, RS corrections, optional pose and overlay.
    Detect(cli::detect::DetectArgs),
    /// Render a dataset from a TOML spec
    Synth(cli::synth::SynthArgs),
    /// Run one detector over a dataset and log every result to MCAP.
    Run(cli::run::RunArgs),
    /// Compute detection rates, corner errors and speed from run logs.
    Eval(cli::evaluate::EvalArgs),
    /// Write the paper's tables and figures from `eval` output.
    Report(cli::report::ReportArgs),
    /// Compare a run's metrics with a committed baseline; fail on regressions.
    Gate(cli::gate::GateArgs),
    /// Time ours against each peer on the same frames, interleaved, with a noise band.
    Speed(cli::speed::SpeedArgs),
    /// Everything from nothing: render datasets, run all detectors, evaluate, report.
    Reproduce(cli::reproduce::ReproduceArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match &cli.command {
        Command::Generate(args) => cli::generate::run(args),
        Command::Detect(args) => cli::detect::run(args),
        Command::Synth(args) => cli::synth::run(args),
        Command::Run(args) => cli::run::run(args),
        Command::Eval(args) => cli::evaluate::run(args),
        Command::Report(args) => cli::report::run(args),
        Command::Reproduce(args) => cli::reproduce::run(args),
        Command::Speed(args) => cli::speed::run(args),
        Command::Gate(args) => match cli::gate::run(args) {
            // A failed gate is a verdict, not an error: exit 1 after its diff.
            Ok(false) => return ExitCode::from(1),
            other => other.map(|_| ()),
        },
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
