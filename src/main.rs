//! The `chronotope` binary.

use clap::Parser;
use std::io::IsTerminal;
use tracing_subscriber::EnvFilter;

fn main() -> std::process::ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new("info")),
        )
        .with_writer(std::io::stderr)
        .with_ansi(std::io::stderr().is_terminal())
        .with_target(false)
        .init();
    let cli = chronotope::cli::Cli::parse();
    // Batch commands only: a live launch's real-time node must not share a heap lock with
    // the nodes that map and free hundreds of MB (docs/performance.md).
    if matches!(
        cli.command,
        chronotope::cli::Command::Replay(_)
            | chronotope::cli::Command::Check(_)
            | chronotope::cli::Command::Mesh(_)
    ) {
        limit_malloc_arenas();
    }
    // rayon's pool, made here and named (after the allocator's settings: its threads
    // allocate as they start): its threads would otherwise take the name (and the
    // scheduling policy) of whichever thread first asks for them, a replay's mesher run
    // ahead or a live node's thread. Its size is rayon's default (`RAYON_NUM_THREADS`, or
    // one per core).
    let _ = rayon::ThreadPoolBuilder::new()
        .thread_name(|i| format!("rayon {i}"))
        .build_global();
    match chronotope::cli::run(cli) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            tracing::error!("{e}");
            std::process::ExitCode::FAILURE
        }
    }
}

/// glibc gives every thread that allocates its own heap ("arena"), up to eight per core, and
/// keeps what each one freed: a replay's threads (rayon's and the checker's resolutions)
/// then hold a sixth to a third more memory than they use. One arena keeps the peak close
/// to what is in use at no measured cost in speed (the 128³ machine-tool replay peaked at
/// 283-289 MB with one, 304-330 MB with two, in the same 4.6 s; docs/performance.md). Not
/// for a live launch: there a real-time node sharing an arena with the mesher waited on
/// its lock (carving latency p99 55 ms instead of 2 ms). `MALLOC_ARENA_MAX`, if set, is
/// left to decide.
fn limit_malloc_arenas() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    if std::env::var_os("MALLOC_ARENA_MAX").is_none() {
        // SAFETY: mallopt only sets a tunable of the allocator; called before the command
        // starts any thread.
        unsafe {
            libc::mallopt(libc::M_ARENA_MAX, 1);
        }
    }
}
