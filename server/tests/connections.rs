//! What a client may hold of the server (`hdlod serve` limits, docs/api.md):
//! a slow request head or an idle connection is dropped after its timeout,
//! the connection over the cap gets a 503 and is closed, the stream over
//! its cap a 503; a stream message over the limit closes the stream with
//! 1009 and a reason; SIGTERM closes open streams with 1001 and ends the
//! server.

mod common;

use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::{Duration, Instant};

use common::Server;
use futures_util::{SinkExt, StreamExt};
use serde_json::{Value, json};
use tokio_tungstenite::tungstenite::Message;
use tokio_tungstenite::tungstenite::protocol::frame::coding::CloseCode;

fn connect(server: &Server) -> TcpStream {
    let socket = TcpStream::connect(server.base.trim_start_matches("http://")).unwrap();
    socket
        .set_read_timeout(Some(Duration::from_secs(20)))
        .unwrap();
    socket
}

/// Reads until the server closes; how long that took and what it sent.
fn until_closed(socket: &mut TcpStream) -> (Duration, String) {
    let start = Instant::now();
    let mut answer = Vec::new();
    let _ = socket.read_to_end(&mut answer);
    (
        start.elapsed(),
        String::from_utf8_lossy(&answer).into_owned(),
    )
}

fn ws_url(server: &Server) -> String {
    server
        .url("/api/v1/scenes/sample-1/stream")
        .replace("http://", "ws://")
}

fn view() -> Value {
    json!({"time": 1000.0, "camera": {"position": [150.0, 120.0, 150.0], "target": [0.0, 20.0, 0.0]}})
}

#[test]
fn a_slow_head_and_an_idle_connection_are_dropped() {
    let server = Server::sample_with(2, &["--header-timeout", "2", "--idle-timeout", "1"]);
    // Half a head, then nothing (before: open for 45 s and more).
    let mut slow = connect(&server);
    slow.write_all(b"GET /healthz HTTP/1.1\r\nHost: x\r\nX-Slow: ")
        .unwrap();
    let (took, _) = until_closed(&mut slow);
    assert!(
        took >= Duration::from_millis(1800) && took < Duration::from_secs(6),
        "dropped after {took:?}"
    );
    // Nothing at all.
    let mut idle = connect(&server);
    let (took, _) = until_closed(&mut idle);
    assert!(
        took >= Duration::from_millis(800) && took < Duration::from_secs(5),
        "dropped after {took:?}"
    );
    // A request, then nothing: answered, then dropped.
    let mut kept = connect(&server);
    kept.write_all(b"GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n")
        .unwrap();
    let (took, text) = until_closed(&mut kept);
    assert!(text.starts_with("HTTP/1.1 200"), "{text}");
    assert!(took < Duration::from_secs(6), "dropped after {took:?}");
}

#[test]
fn the_connection_over_the_cap_is_refused() {
    let server = Server::sample_with(2, &["--max-connections", "4", "--idle-timeout", "30"]);
    let held: Vec<TcpStream> = (0..4).map(|_| connect(&server)).collect();
    // The four are accepted before the fifth arrives.
    std::thread::sleep(Duration::from_millis(300));
    let mut fifth = connect(&server);
    let (took, text) = until_closed(&mut fifth);
    assert!(took < Duration::from_secs(5));
    assert!(text.starts_with("HTTP/1.1 503"), "{text}");
    let body: Value = serde_json::from_str(text.split_once("\r\n\r\n").unwrap().1).unwrap();
    assert_eq!(body["error"]["field"], "connection", "{body}");
    assert_eq!(body["error"]["status"], 503);
    // One closed frees a place.
    drop(held);
    std::thread::sleep(Duration::from_millis(300));
    let mut next = connect(&server);
    next.write_all(b"GET /healthz HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n")
        .unwrap();
    let (_, text) = until_closed(&mut next);
    assert!(text.starts_with("HTTP/1.1 200"), "{text}");
}

#[test]
fn the_stream_over_the_cap_is_refused() {
    let server = Server::sample_with(2, &["--max-streams", "1"]);
    let runtime = tokio::runtime::Runtime::new().unwrap();
    runtime.block_on(async {
        let (_first, _) = tokio_tungstenite::connect_async(ws_url(&server))
            .await
            .unwrap();
        match tokio_tungstenite::connect_async(ws_url(&server)).await {
            Err(tokio_tungstenite::tungstenite::Error::Http(response)) => {
                assert_eq!(response.status(), 503);
                let body: Value =
                    serde_json::from_slice(response.body().as_deref().unwrap()).unwrap();
                assert_eq!(body["error"]["field"], "stream", "{body}");
            }
            other => panic!("a second stream: {other:?}"),
        }
    });
}

/// The close frame a stream gets after `send`, if any.
async fn close_after(url: &str, send: Message) -> Option<(CloseCode, String)> {
    let (mut socket, _) = tokio_tungstenite::connect_async(url).await.unwrap();
    socket.send(send).await.unwrap();
    loop {
        match tokio::time::timeout(Duration::from_secs(20), socket.next()).await {
            Ok(Some(Ok(Message::Close(frame)))) => {
                return frame.map(|f| (f.code, f.reason.to_string()));
            }
            Ok(Some(Ok(_))) => continue,
            Ok(Some(Err(_)) | None) => return None,
            Err(_) => panic!("the stream neither answered nor closed"),
        }
    }
}

#[test]
fn a_message_over_the_limit_closes_the_stream_with_1009() {
    let server = Server::sample(2);
    let limit = 64 * 1024;
    let runtime = tokio::runtime::Runtime::new().unwrap();
    runtime.block_on(async {
        // One byte over (before: the TCP connection dropped, no frame).
        let over = format!("{{\"pad\": \"{}\"}}", "x".repeat(limit - 11 + 1));
        assert_eq!(over.len(), limit + 1);
        let (code, reason) = close_after(&ws_url(&server), Message::text(over))
            .await
            .expect("a close frame");
        assert_eq!(code, CloseCode::Size);
        assert!(reason.contains("65536"), "{reason}");
        // At the limit, an ordinary answer (an error naming the field).
        let at = format!("{{\"pad\": \"{}\"}}", "x".repeat(limit - 11));
        let (mut socket, _) = tokio_tungstenite::connect_async(ws_url(&server))
            .await
            .unwrap();
        socket.send(Message::text(at)).await.unwrap();
        let Some(Ok(Message::Text(text))) = socket.next().await else {
            panic!("no answer")
        };
        let answer: Value = serde_json::from_str(text.as_str()).unwrap();
        assert_eq!(answer["error"]["status"], 400, "{answer}");
    });
}

#[test]
fn sigterm_closes_streams_with_1001_and_ends_the_server() {
    let mut server = Server::sample(2);
    let runtime = tokio::runtime::Runtime::new().unwrap();
    runtime.block_on(async {
        let (mut socket, _) = tokio_tungstenite::connect_async(ws_url(&server))
            .await
            .unwrap();
        socket
            .send(Message::text(view().to_string()))
            .await
            .unwrap();
        let Some(Ok(Message::Text(_))) = socket.next().await else {
            panic!("no answer")
        };
        let status = std::process::Command::new("kill")
            .args(["-TERM", &server.pid().to_string()])
            .status()
            .unwrap();
        assert!(status.success());
        let frame = loop {
            match tokio::time::timeout(Duration::from_secs(20), socket.next()).await {
                Ok(Some(Ok(Message::Close(frame)))) => break frame,
                Ok(Some(Ok(_))) => continue,
                other => panic!("no close frame: {other:?}"),
            }
        };
        let frame = frame.expect("a close code");
        assert_eq!(frame.code, CloseCode::Away);
        assert!(frame.reason.contains("shutting down"), "{}", frame.reason);
    });
    let exit = server.wait_for_exit(Duration::from_secs(15));
    assert_eq!(exit, Some(true), "the server ends cleanly");
}
