//! The accept loop, in place of `axum::serve`, which has no hold on what a
//! connection may do: every connection goes through [`Guarded`] (JSON
//! 414/431, the idle timeout) and hyper's header read timeout; at most
//! [`Limits::max_connections`] are open at once (the one over gets a 503
//! and is closed: a flood of idle or half-sent requests cannot hold the
//! server's memory and descriptors); and shutdown drains: no new
//! connection, requests in flight finish within the grace period,
//! WebSocket streams are closed with 1001 (going away).

use std::future::Future;
use std::sync::Arc;
use std::time::Duration;

use axum::Router;
use axum::http::StatusCode;
use hyper::server::conn::http1;
use hyper_util::rt::{TokioIo, TokioTimer};
use hyper_util::service::TowerToHyperService;
use tokio::io::AsyncWriteExt;
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::Semaphore;

use super::AppState;
use super::connection::{Guarded, MAX_HEADERS, raw_answer};
use super::error::ApiError;

/// What clients may hold of the server (`hdlod serve` flags; docs/api.md).
#[derive(Debug, Clone, Copy)]
pub struct Limits {
    /// A request head must arrive whole within this.
    pub header_timeout: Duration,
    /// A connection waiting on its client longer than this is closed.
    pub idle_timeout: Duration,
    /// Open connections, WebSocket streams included.
    pub max_connections: usize,
    /// WebSocket streams.
    pub max_streams: usize,
    /// How long shutdown waits for requests and streams in flight.
    pub grace: Duration,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            header_timeout: Duration::from_secs(10),
            idle_timeout: Duration::from_secs(60),
            max_connections: 1024,
            max_streams: 256,
            grace: Duration::from_secs(10),
        }
    }
}

/// Serves `app` on `listener` until `shutdown` resolves, then drains.
pub async fn serve(
    listener: TcpListener,
    app: Router,
    state: Arc<AppState>,
    limits: Limits,
    shutdown: impl Future<Output = ()>,
) {
    let connections = Arc::new(Semaphore::new(limits.max_connections));
    let (stop, stopped) = tokio::sync::watch::channel(false);
    tokio::pin!(shutdown);
    loop {
        let socket = tokio::select! {
            accepted = listener.accept() => match accepted {
                Ok((socket, _)) => socket,
                Err(e) => {
                    // Out of descriptors, most likely: a pause lets some close.
                    tracing::warn!("cannot accept a connection: {e}");
                    tokio::time::sleep(Duration::from_millis(50)).await;
                    continue;
                }
            },
            () = &mut shutdown => break,
        };
        let _ = socket.set_nodelay(true);
        let Ok(permit) = connections.clone().try_acquire_owned() else {
            tokio::spawn(refuse(socket, limits.max_connections));
            continue;
        };
        let service = TowerToHyperService::new(app.clone());
        let stopped = super::raised(stopped.clone());
        tokio::spawn(async move {
            // The permit rides with the socket: through an upgrade it
            // lives as long as the WebSocket stream.
            let io = TokioIo::new(Guarded::new(socket, limits.idle_timeout, permit));
            let connection = http1::Builder::new()
                .timer(TokioTimer::new())
                .header_read_timeout(limits.header_timeout)
                .max_headers(2 * MAX_HEADERS)
                .serve_connection(io, service)
                .with_upgrades();
            tokio::pin!(connection);
            tokio::select! {
                result = connection.as_mut() => {
                    if let Err(e) = result {
                        tracing::debug!("connection ended: {e}");
                    }
                }
                () = stopped => {
                    connection.as_mut().graceful_shutdown();
                    let _ = connection.await;
                }
            }
        });
    }
    drop(listener);
    let _ = stop.send(true);
    state.close_streams();
    let all = u32::try_from(limits.max_connections).unwrap_or(u32::MAX);
    match tokio::time::timeout(limits.grace, connections.acquire_many(all)).await {
        Ok(_) => tracing::info!("all connections closed"),
        Err(_) => tracing::warn!(
            "{} connections still open after {:?}; closing them",
            limits.max_connections - connections.available_permits(),
            limits.grace
        ),
    }
}

/// The connection over the cap: a 503 with the API's error, then closed.
async fn refuse(mut socket: TcpStream, cap: usize) {
    let answer = raw_answer(&ApiError::new(
        StatusCode::SERVICE_UNAVAILABLE,
        Some("connection".into()),
        format!("the server holds its maximum of {cap} connections; try again shortly"),
    ));
    let _ = tokio::time::timeout(Duration::from_secs(1), async {
        socket.write_all(&answer).await?;
        socket.shutdown().await
    })
    .await;
}
