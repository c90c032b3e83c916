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

/// Runs `work` on a pool of `threads` worker threads, or on rayon's global
/// pool (one thread per core) when the user gave no `--threads`.
pub(crate) fn with_threads<T: Send>(
    threads: Option<u64>,
    work: impl FnOnce() -> T + Send,
) -> anyhow::Result<T> {
    use anyhow::Context;
    Ok(match threads {
        Some(n) => rayon::ThreadPoolBuilder::new()
            .num_threads(usize::try_from(n).context("--threads is too large")?)
            .build()
            .context("cannot start worker threads")?
            .install(work),
        None => work(),
    })
}
