//! One client connection as the HTTP layer reads it ([`Guarded`]): the
//! request heads are watched on their way in, so that a request line or a
//! head too long for hyper gets the API's JSON error (hyper would answer
//! 414 or 431 with an empty body, before any service could), and a
//! connection that waits between requests longer than the idle timeout is
//! closed. After a WebSocket upgrade or a chunked body the watch stops:
//! what follows is not HTTP heads.

use std::io;
use std::pin::Pin;
use std::task::{Context, Poll, ready};
use std::time::Duration;

use axum::http::StatusCode;
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::sync::OwnedSemaphorePermit;
use tokio::time::{Instant, Sleep};

use super::error::ApiError;

/// The longest request line (method, path and query, version): a cut with
/// a full view-projection matrix takes under 1 KiB.
pub const MAX_REQUEST_LINE: usize = 8 * 1024;
/// The longest request head, request line and headers.
pub const MAX_HEAD: usize = 64 * 1024;
/// The most header lines in a head; hyper's own bound is set above it
/// (`listener`), so that this one answers first.
pub const MAX_HEADERS: usize = 100;

/// A whole HTTP/1.1 answer with the API's error body, written by hand
/// where no service answers: a head refused here, a connection over the
/// cap.
pub fn raw_answer(error: &ApiError) -> Vec<u8> {
    let body = error.body().to_string();
    let reason = error.status.canonical_reason().unwrap_or("Error");
    let retry = if error.status == StatusCode::SERVICE_UNAVAILABLE {
        "retry-after: 1\r\n"
    } else {
        ""
    };
    format!(
        "HTTP/1.1 {} {reason}\r\ncontent-type: application/json\r\ncontent-length: {}\r\n\
         {retry}connection: close\r\n\r\n{body}",
        error.status.as_u16(),
        body.len()
    )
    .into_bytes()
}

/// Where the reader is in the stream of requests.
enum Place {
    /// In a request head (`at_start`: no byte of it yet).
    Head(Head),
    /// In a body of known length: this many bytes to go.
    Body(u64),
    /// Past anything we follow (an upgrade, a chunked body).
    Off,
    /// A head was refused: this answer is written, then the reader ends.
    Refusing { answer: Vec<u8>, written: usize },
}

#[derive(Default)]
struct Head {
    bytes: usize,
    line: usize,
    headers: usize,
    request_line: bool,
    /// The current header line's first bytes, lower-cased.
    start: Vec<u8>,
    content_length: u64,
    /// Chunked or upgraded: the watch stops after this head.
    leave: bool,
}

impl Head {
    fn new() -> Head {
        Head {
            request_line: true,
            ..Head::default()
        }
    }

    /// One byte of the head; `Some` when it ends the head or breaks a
    /// limit.
    fn push(&mut self, b: u8) -> Option<Result<Place, ApiError>> {
        self.bytes += 1;
        if b != b'\n' {
            self.line += 1;
            if self.start.len() < 64 && b != b'\r' {
                self.start.push(b.to_ascii_lowercase());
            }
            if self.request_line && self.line > MAX_REQUEST_LINE {
                return Some(Err(ApiError::new(
                    StatusCode::URI_TOO_LONG,
                    Some("path".into()),
                    format!("the request line is over {MAX_REQUEST_LINE} bytes"),
                )));
            }
            if self.bytes > MAX_HEAD {
                return Some(Err(ApiError::new(
                    StatusCode::REQUEST_HEADER_FIELDS_TOO_LARGE,
                    Some("headers".into()),
                    format!("the request head is over {MAX_HEAD} bytes"),
                )));
            }
            return None;
        }
        let empty = self.start.is_empty();
        let line = std::mem::take(&mut self.start);
        self.line = 0;
        if self.request_line {
            // Empty lines before a request are allowed (RFC 9112 2.2).
            self.request_line = empty;
            return None;
        }
        if !empty {
            self.headers += 1;
            if self.headers > MAX_HEADERS {
                return Some(Err(ApiError::new(
                    StatusCode::REQUEST_HEADER_FIELDS_TOO_LARGE,
                    Some("headers".into()),
                    format!("the request has over {MAX_HEADERS} headers"),
                )));
            }
            self.header(&line);
            return None;
        }
        Some(Ok(if self.leave {
            Place::Off
        } else if self.content_length > 0 {
            Place::Body(self.content_length)
        } else {
            Place::Head(Head::new())
        }))
    }

    fn header(&mut self, line: &[u8]) {
        if let Some(value) = line.strip_prefix(b"content-length:") {
            // hyper checks the value; a bad one ends the connection anyway.
            self.content_length = std::str::from_utf8(value)
                .ok()
                .and_then(|v| v.trim().parse().ok())
                .unwrap_or(0);
        } else if line.starts_with(b"transfer-encoding:") || line.starts_with(b"upgrade:") {
            self.leave = true;
        }
    }
}

/// A connection's transport with the head watch and the idle timeout.
pub struct Guarded<T> {
    inner: T,
    place: Place,
    idle: Duration,
    deadline: Pin<Box<Sleep>>,
    /// The connection's place under the cap, given back when it closes.
    _permit: OwnedSemaphorePermit,
}

impl<T> Guarded<T> {
    pub fn new(inner: T, idle: Duration, permit: OwnedSemaphorePermit) -> Guarded<T> {
        Guarded {
            inner,
            place: Place::Head(Head::new()),
            idle,
            deadline: Box::pin(tokio::time::sleep(idle)),
            _permit: permit,
        }
    }

    fn touched(&mut self) {
        let at = Instant::now() + self.idle;
        self.deadline.as_mut().reset(at);
    }

    /// Whether the connection waits on the client: between requests or
    /// inside a body. Within a head the header timeout rules (hyper's),
    /// after an upgrade the stream's own.
    fn waiting(&self) -> bool {
        match &self.place {
            Place::Head(h) => h.bytes == 0,
            Place::Body(_) => true,
            Place::Off | Place::Refusing { .. } => false,
        }
    }

    /// Follows the bytes just read; returns how many of them the HTTP layer
    /// gets (those before a refused limit).
    fn follow(&mut self, bytes: &[u8]) -> usize {
        let mut i = 0;
        while i < bytes.len() {
            match &mut self.place {
                Place::Off | Place::Refusing { .. } => return bytes.len(),
                Place::Body(left) => {
                    let n = (*left).min((bytes.len() - i) as u64);
                    *left -= n;
                    i += n as usize;
                    if *left == 0 {
                        self.place = Place::Head(Head::new());
                    }
                }
                Place::Head(head) => {
                    let b = bytes[i];
                    i += 1;
                    match head.push(b) {
                        None => {}
                        Some(Ok(next)) => self.place = next,
                        Some(Err(e)) => {
                            tracing::debug!("refused a request head: {}", e.message);
                            self.place = Place::Refusing {
                                answer: raw_answer(&e),
                                written: 0,
                            };
                            return i - 1;
                        }
                    }
                }
            }
        }
        bytes.len()
    }
}

impl<T: AsyncRead + AsyncWrite + Unpin> AsyncRead for Guarded<T> {
    fn poll_read(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        let this = &mut *self;
        if let Place::Refusing { answer, written } = &mut this.place {
            // The answer goes out, then the HTTP layer reads the end.
            while *written < answer.len() {
                let n = ready!(Pin::new(&mut this.inner).poll_write(cx, &answer[*written..]))?;
                if n == 0 {
                    return Poll::Ready(Err(io::ErrorKind::WriteZero.into()));
                }
                *written += n;
            }
            ready!(Pin::new(&mut this.inner).poll_flush(cx))?;
            return Poll::Ready(Ok(()));
        }
        let before = buf.filled().len();
        match Pin::new(&mut this.inner).poll_read(cx, buf) {
            Poll::Ready(Ok(())) => {
                let filled = buf.filled().len();
                if filled > before {
                    this.touched();
                    let kept = this.follow(&buf.filled()[before..filled]);
                    buf.set_filled(before + kept);
                    if kept == 0 && matches!(this.place, Place::Refusing { .. }) {
                        // Nothing for the HTTP layer: answer at once.
                        return Pin::new(this).poll_read(cx, buf);
                    }
                }
                Poll::Ready(Ok(()))
            }
            Poll::Ready(Err(e)) => Poll::Ready(Err(e)),
            Poll::Pending => {
                if this.waiting() && this.deadline.as_mut().poll(cx).is_ready() {
                    return Poll::Ready(Err(io::Error::new(
                        io::ErrorKind::TimedOut,
                        "idle connection closed",
                    )));
                }
                Poll::Pending
            }
        }
    }
}

impl<T: AsyncWrite + Unpin> AsyncWrite for Guarded<T> {
    fn poll_write(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        data: &[u8],
    ) -> Poll<io::Result<usize>> {
        let written = ready!(Pin::new(&mut self.inner).poll_write(cx, data))?;
        if written > 0 {
            self.touched();
        }
        Poll::Ready(Ok(written))
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.inner).poll_flush(cx)
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.inner).poll_shutdown(cx)
    }

    fn poll_write_vectored(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[io::IoSlice<'_>],
    ) -> Poll<io::Result<usize>> {
        let written = ready!(Pin::new(&mut self.inner).poll_write_vectored(cx, bufs))?;
        if written > 0 {
            self.touched();
        }
        Poll::Ready(Ok(written))
    }

    fn is_write_vectored(&self) -> bool {
        self.inner.is_write_vectored()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn follow(chunks: &[&[u8]]) -> (Vec<usize>, bool) {
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_time()
            .build()
            .unwrap();
        rt.block_on(async {
            let (a, _b) = tokio::io::duplex(64);
            let permit = std::sync::Arc::new(tokio::sync::Semaphore::new(1))
                .try_acquire_owned()
                .unwrap();
            let mut g = Guarded::new(a, Duration::from_secs(1), permit);
            let kept = chunks.iter().map(|c| g.follow(c)).collect();
            (kept, matches!(g.place, Place::Refusing { .. }))
        })
    }

    #[test]
    fn heads_and_bodies_are_followed_across_requests() {
        let post = b"POST /cut HTTP/1.1\r\nContent-Length: 5\r\n\r\nhello";
        let get = b"GET / HTTP/1.1\r\nHost: x\r\n\r\n";
        assert_eq!(
            follow(&[post, get, post]),
            (vec![post.len(), get.len(), post.len()], false)
        );
        // A body that looks like a long line is not a request line.
        let long = format!(
            "POST /cut HTTP/1.1\r\ncontent-length: {n}\r\n\r\n{}",
            "x".repeat(20_000),
            n = 20_000
        );
        assert!(!follow(&[long.as_bytes(), get]).1);
    }

    #[test]
    fn a_long_request_line_is_refused_where_it_passes_the_limit() {
        let line = format!("GET /{} HTTP/1.1\r\n", "a".repeat(MAX_REQUEST_LINE));
        let (kept, refused) = follow(&[line.as_bytes()]);
        assert!(refused);
        assert_eq!(kept, vec![MAX_REQUEST_LINE]);
    }

    #[test]
    fn after_an_upgrade_nothing_is_followed() {
        let up = b"GET /stream HTTP/1.1\r\nUpgrade: websocket\r\n\r\n";
        let frames = vec![b'a'; MAX_HEAD * 2];
        assert!(!follow(&[up, &frames]).1);
    }
}
