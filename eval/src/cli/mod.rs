//! One module per subcommand; each exposes `XArgs` (clap) and `run`.

pub mod detect;
pub mod detect_bag;
pub mod evaluate;
pub mod gate;
pub mod generate;
pub mod progress;
pub mod report;
pub mod reproduce;
pub mod run;
pub mod speed;
pub mod synth;
