//! `hdlod serve [--addr 127.0.0.1:8080] TREE...`: the HTTP API over the
//! given trees. SIGHUP, or a change on disk (a tree replaced by a rename as
//! `hdlod build` does, or its manifest or cluster table rewritten), re-reads
//! every tree; requests in flight finish on the trees they started with.
//! SIGTERM or Ctrl-C drain the server (`api::listener`): no new
//! connection, requests in flight finish, streams close with 1001.

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::time::Duration;

use anyhow::Context;
use hdlod::tree::format::{CLUSTERS_FILE, INDEX_FILE, MANIFEST_FILE, OBJECTS_INDEX_FILE};
use notify::{Event, EventKind, RecommendedWatcher, RecursiveMode, Watcher};

use crate::api::listener::{self, Limits};
use crate::api::{self, AppState, Cors};
use crate::protocol;

#[derive(clap::Args)]
pub struct Args {
    /// Address to listen on (port 0: any free port; the bound address is
    /// printed on stdout).
    #[arg(long, default_value = "127.0.0.1:8080")]
    addr: String,
    /// Tree directories (hdlod trees), one scene each.
    #[arg(required = true)]
    trees: Vec<PathBuf>,
    /// Reload on SIGHUP only, not when a tree changes on disk (for file
    /// systems without change notification).
    #[arg(long)]
    no_watch: bool,
    /// An origin (`https://example.com`) that may call every route from a
    /// web page, POST cuts included; repeatable, `*` for any. Without it
    /// any origin may use the read-only (GET) routes.
    #[arg(long = "cors-origin", value_name = "ORIGIN")]
    cors_origins: Vec<String>,
    /// Seconds a client has to send a whole request head.
    #[arg(long, value_name = "SECONDS", default_value_t = 10.0)]
    header_timeout: f64,
    /// Seconds a connection may wait on its client (between requests, in
    /// a body) before it is closed.
    #[arg(long, value_name = "SECONDS", default_value_t = 60.0)]
    idle_timeout: f64,
    /// Open connections at once, WebSocket streams included; the one over
    /// gets a 503 and is closed.
    #[arg(long, value_name = "N", default_value_t = 1024)]
    max_connections: usize,
    /// WebSocket streams open at once; the one over gets a 503.
    #[arg(long, value_name = "N", default_value_t = 256)]
    max_streams: usize,
    /// Seconds shutdown waits for requests and streams in flight.
    #[arg(long, value_name = "SECONDS", default_value_t = 10.0)]
    shutdown_grace: f64,
}

fn seconds(flag: &str, value: f64) -> anyhow::Result<Duration> {
    Duration::try_from_secs_f64(value)
        .ok()
        .filter(|d| !d.is_zero())
        .with_context(|| format!("--{flag} {value}: must be a number of seconds > 0"))
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let cors = Cors::from_args(&args.cors_origins)?;
    anyhow::ensure!(
        args.max_connections >= 1,
        "--max-connections must be at least 1"
    );
    anyhow::ensure!(args.max_streams >= 1, "--max-streams must be at least 1");
    let limits = Limits {
        header_timeout: seconds("header-timeout", args.header_timeout)?,
        idle_timeout: seconds("idle-timeout", args.idle_timeout)?,
        max_connections: args.max_connections,
        max_streams: args.max_streams,
        grace: seconds("shutdown-grace", args.shutdown_grace)?,
    };
    serve_trees(&args.addr, args.trees, !args.no_watch, cors, limits)
}

/// Serves `trees` on `addr` until Ctrl-C, reloading them when they change
/// on disk (what `hdlod demo` runs).
pub fn serve(addr: &str, trees: Vec<PathBuf>) -> anyhow::Result<()> {
    serve_trees(addr, trees, true, Cors::default(), Limits::default())
}

/// Resolves on SIGTERM or Ctrl-C (SIGINT).
async fn stop_signal() {
    use tokio::signal::unix::{SignalKind, signal};
    match signal(SignalKind::terminate()) {
        Ok(mut term) => {
            tokio::select! {
                _ = term.recv() => {}
                _ = tokio::signal::ctrl_c() => {}
            }
        }
        Err(e) => {
            tracing::warn!("cannot listen for SIGTERM ({e}): Ctrl-C alone stops the server");
            let _ = tokio::signal::ctrl_c().await;
        }
    }
    tracing::info!("shutting down: draining connections");
}

fn serve_trees(
    addr: &str,
    trees: Vec<PathBuf>,
    watching: bool,
    cors: Cors,
    limits: Limits,
) -> anyhow::Result<()> {
    let state = AppState::load(trees.clone(), &limits)?;
    if watching {
        watch(state.clone(), &trees)?;
    }
    let runtime = tokio::runtime::Runtime::new()?;
    runtime.block_on(async move {
        let listener = tokio::net::TcpListener::bind(addr)
            .await
            .with_context(|| format!("cannot listen on {addr}"))?;
        let addr = listener.local_addr()?;
        for name in state.scenes().keys() {
            tracing::info!(
                "scene {name:?} at http://{addr}{}",
                protocol::scene_path(name)
            );
        }
        println!("listening on http://{addr}");
        let checker = state.clone();
        tokio::task::spawn_blocking(move || {
            for e in checker.check_geometry() {
                tracing::error!("{e}: requests for that geometry will fail");
            }
        });
        let reloader = state.clone();
        tokio::spawn(async move {
            let Ok(mut hup) =
                tokio::signal::unix::signal(tokio::signal::unix::SignalKind::hangup())
            else {
                tracing::warn!("cannot listen for SIGHUP: trees will not be reloaded");
                return;
            };
            while hup.recv().await.is_some() {
                let state = reloader.clone();
                match tokio::task::spawn_blocking(move || reload(&state, "SIGHUP")).await {
                    Ok(()) => {}
                    Err(e) => tracing::error!("reload failed: {e}"),
                }
            }
        });
        let app = api::router(state.clone(), &cors);
        listener::serve(listener, app, state, limits, stop_signal()).await;
        Ok(())
    })
}

fn reload(state: &AppState, why: &str) {
    let errors = state.reload();
    if errors.is_empty() {
        tracing::info!("trees reloaded ({why})");
    }
    for e in errors {
        tracing::error!("reload ({why}) kept the previous tree: {e}");
    }
}

/// Changes are gathered until the trees have been quiet this long, so that
/// a replacement (rename away, rename in) or a rewrite of both files is
/// one reload.
const QUIET: Duration = Duration::from_millis(300);

/// Watches each tree directory and its parent (the directory itself is
/// replaced by a rename, which only the parent sees) from a thread of its
/// own that reloads every tree after a change.
fn watch(state: Arc<AppState>, trees: &[PathBuf]) -> anyhow::Result<()> {
    let dirs: Vec<PathBuf> = trees
        .iter()
        .map(|t| std::path::absolute(t).with_context(|| format!("{}", t.display())))
        .collect::<anyhow::Result<_>>()?;
    let (tx, rx) = std::sync::mpsc::channel();
    let mut watcher = notify::recommended_watcher(tx).context("cannot watch the trees")?;
    for dir in &dirs {
        if let Some(parent) = dir.parent() {
            watcher
                .watch(parent, RecursiveMode::NonRecursive)
                .with_context(|| format!("cannot watch {}", parent.display()))?;
        }
        watcher
            .watch(dir, RecursiveMode::NonRecursive)
            .with_context(|| format!("cannot watch {}", dir.display()))?;
    }
    std::thread::spawn(move || watch_loop(&state, watcher, &rx, &dirs));
    Ok(())
}

fn watch_loop(
    state: &AppState,
    mut watcher: RecommendedWatcher,
    rx: &Receiver<notify::Result<Event>>,
    dirs: &[PathBuf],
) {
    while let Ok(event) = rx.recv() {
        match event {
            Ok(e) if concerns(&e, dirs) => {}
            Ok(_) => continue,
            Err(e) => {
                tracing::warn!("file watch: {e}");
                continue;
            }
        }
        loop {
            match rx.recv_timeout(QUIET) {
                Ok(_) => {}
                Err(RecvTimeoutError::Timeout) => break,
                Err(RecvTimeoutError::Disconnected) => return,
            }
        }
        reload(state, "changed on disk");
        // A replaced directory is a new one: watch it (the old watch went
        // with the old directory).
        for dir in dirs {
            let _ = watcher.unwatch(dir);
            if let Err(e) = watcher.watch(dir, RecursiveMode::NonRecursive) {
                tracing::warn!("cannot watch {}: {e}", dir.display());
            }
        }
    }
}

/// Whether an event may have changed a tree: the directory itself renamed
/// or created, or its manifest, cluster table or an index written. Removals are not
/// (the old directory being deleted after a replacement), nor reads.
fn concerns(event: &Event, dirs: &[PathBuf]) -> bool {
    if matches!(event.kind, EventKind::Remove(_) | EventKind::Access(_)) {
        return false;
    }
    event.paths.iter().any(|p| {
        dirs.iter().any(|d| p == d)
            || p.parent()
                .is_some_and(|parent| dirs.iter().any(|d| parent == d))
                && p.file_name().is_some_and(|n| {
                    [MANIFEST_FILE, CLUSTERS_FILE, INDEX_FILE, OBJECTS_INDEX_FILE]
                        .contains(&n.to_str().unwrap_or_default())
                })
    })
}
