//! One module per subcommand; each exposes `XArgs` (clap) and `run`.

pub mod generate;
pub mod output;
