//! What the browser benchmarks share (`hdlod bench image`, `hdlod bench
//! viewer`): a tree served on loopback by the real router, and a node
//! driver of `tools/browser/` run against it, whose stdout is one JSON
//! report.

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{Context, bail};

use crate::api::{self, AppState, Cors};

/// A tree served on loopback for as long as this lives.
pub struct Served {
    pub state: std::sync::Arc<AppState>,
    /// The tree's (first) scene.
    pub scene: String,
    pub base: String,
    _runtime: tokio::runtime::Runtime,
}

/// The driver `tools/browser/NAME` of the repository's `tools` directory,
/// checked before anything is loaded.
pub fn driver(tools: &Path, name: &str) -> anyhow::Result<PathBuf> {
    let driver = tools.join("browser").join(name);
    if !driver.is_file() {
        bail!(
            "{} not found: run from the repository's root or give --tools DIR",
            driver.display()
        );
    }
    Ok(driver)
}

pub fn serve(tree: &Path) -> anyhow::Result<Served> {
    let state = AppState::load(vec![tree.to_owned()], &Default::default())?;
    let scene = state
        .scenes()
        .keys()
        .next()
        .cloned()
        .context("the tree holds no scene")?;
    let runtime = tokio::runtime::Runtime::new()?;
    let listener = runtime
        .block_on(tokio::net::TcpListener::bind("127.0.0.1:0"))
        .context("cannot listen on loopback")?;
    let base = format!("http://{}", listener.local_addr()?);
    let served = state.clone();
    runtime.spawn(async move {
        let _ = axum::serve(listener, api::router(served, &Cors::default())).await;
    });
    Ok(Served {
        state,
        scene,
        base,
        _runtime: runtime,
    })
}

/// The driver's JSON report, read as `T`.
pub fn drive<T: serde::de::DeserializeOwned>(driver: &Path, args: &[String]) -> anyhow::Result<T> {
    let run = Command::new("node")
        .arg(driver)
        .args(args)
        .output()
        .context("cannot run node (the driver needs node and tools/node_modules)")?;
    if !run.status.success() {
        bail!(
            "the driver failed: {}",
            String::from_utf8_lossy(&run.stderr)
        );
    }
    serde_json::from_slice(&run.stdout).with_context(|| {
        format!(
            "the driver's report is not JSON: {}",
            String::from_utf8_lossy(&run.stdout)
        )
    })
}
