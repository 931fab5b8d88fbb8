//! `hdlod serve [--addr 127.0.0.1:8080] TREE...`: the HTTP API over the
//! given trees. SIGHUP re-reads every tree from disk; requests in flight
//! finish on the trees they started with.

use std::path::PathBuf;

use anyhow::Context;

use crate::api::{self, AppState};

#[derive(clap::Args)]
pub struct Args {
    /// Address to listen on (port 0: any free port; the bound address is
    /// printed on stdout).
    #[arg(long, default_value = "127.0.0.1:8080")]
    addr: String,
    /// Tree directories (hdlod-tree/1), one scene each.
    #[arg(required = true)]
    trees: Vec<PathBuf>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    serve(&args.addr, args.trees)
}

/// Serves `trees` on `addr` until Ctrl-C (also what `hdlod demo` runs).
pub fn serve(addr: &str, trees: Vec<PathBuf>) -> anyhow::Result<()> {
    let state = AppState::load(trees)?;
    let runtime = tokio::runtime::Runtime::new()?;
    runtime.block_on(async move {
        let listener = tokio::net::TcpListener::bind(addr)
            .await
            .with_context(|| format!("cannot listen on {addr}"))?;
        let addr = listener.local_addr()?;
        for name in state.scenes().keys() {
            tracing::info!(
                "scene {name:?} at http://{addr}{}",
                api::cut::scene_path(name)
            );
        }
        println!("listening on http://{addr}");
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
                match tokio::task::spawn_blocking(move || state.reload()).await {
                    Ok(errors) if errors.is_empty() => tracing::info!("trees reloaded"),
                    Ok(errors) => errors
                        .iter()
                        .for_each(|e| tracing::error!("reload kept the previous tree: {e}")),
                    Err(e) => tracing::error!("reload failed: {e}"),
                }
            }
        });
        axum::serve(listener, api::router(state))
            .with_graceful_shutdown(async {
                let _ = tokio::signal::ctrl_c().await;
            })
            .await?;
        Ok(())
    })
}
