//! The HTTP side: a few threads answering the page's routes from a [`Content`].

use super::ImageData;
use std::io::{Cursor, Read};
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use thiserror::Error;
use tiny_http::{Header, Method, Request, Response, ResponseBox};

#[derive(Debug, Error)]
pub enum PreviewError {
    #[error("cannot serve the preview at {address}: {message}")]
    Bind {
        address: SocketAddr,
        message: String,
    },
}

/// The page: markup, style and script in one file, so nothing is fetched from elsewhere.
const PAGE: &str = include_str!("page.html");

/// Threads answering requests; a long poll holds one for up to [`super::live::LONG_POLL`].
const WORKERS: usize = 4;

/// What the page's `/state?since=F&errors=K` asks: wait for a frame newer than `F` (when
/// given), and send the error series from sample `K` on.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct StateQuery {
    pub since: Option<u64>,
    pub errors_from: usize,
}

/// What the routes serve: the live render's or the files'.
pub(crate) trait Content: Send + Sync + 'static {
    /// The page's state as JSON.
    fn state(&self, query: StateQuery) -> String;
    /// Image `index`, when there is one.
    fn image(&self, index: usize) -> Option<ImageData>;
}

/// A running server; dropping it stops the workers and closes the port.
pub struct Server {
    address: SocketAddr,
    http: Arc<tiny_http::Server>,
    stop: Arc<AtomicBool>,
    workers: Vec<JoinHandle<()>>,
}

impl Server {
    pub(crate) fn start(
        address: SocketAddr,
        content: Arc<dyn Content>,
    ) -> Result<Self, PreviewError> {
        let bind = |message: String| PreviewError::Bind { address, message };
        let http = tiny_http::Server::http(address).map_err(|e| bind(e.to_string()))?;
        let bound = http
            .server_addr()
            .to_ip()
            .ok_or_else(|| bind("not an IP socket".into()))?;
        let http = Arc::new(http);
        let stop = Arc::new(AtomicBool::new(false));
        let loopback = bound.ip().is_loopback();
        let mut workers = Vec::with_capacity(WORKERS);
        for _ in 0..WORKERS {
            let (serving, content, stopping) = (http.clone(), content.clone(), stop.clone());
            let worker = std::thread::Builder::new()
                .name("preview-http".into())
                .spawn(move || loop {
                    match serving.recv() {
                        // A client that went away needs no answer.
                        Ok(request) => {
                            let _ = answer_request(request, &*content, loopback);
                        }
                        // Unblocked by `drop`, or a failed accept, which stops nothing else.
                        Err(_) if stopping.load(Ordering::SeqCst) => break,
                        Err(_) => {}
                    }
                });
            match worker {
                Ok(w) => workers.push(w),
                Err(e) => {
                    // Those already started must not keep the port open.
                    drop(Server {
                        address: bound,
                        http,
                        stop,
                        workers,
                    });
                    return Err(bind(format!("cannot start a thread: {e}")));
                }
            }
        }
        Ok(Server {
            address: bound,
            http,
            stop,
            workers,
        })
    }

    /// The address bound to (with the port the system chose for port 0).
    pub fn address(&self) -> SocketAddr {
        self.address
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        // One wake-up for each worker: each takes one and, seeing `stop`, ends.
        for _ in &self.workers {
            self.http.unblock();
        }
        for worker in self.workers.drain(..) {
            // A worker that panicked has nothing left to clean up.
            let _ = worker.join();
        }
        // `http` goes after this, the last handle on the listener, which closes it.
    }
}

fn answer_request(request: Request, content: &dyn Content, loopback: bool) -> std::io::Result<()> {
    let response = route(&request, content, loopback);
    request.respond(response)
}

fn header(name: &str, value: &str) -> Header {
    // Every name and value here is a constant or a number: ASCII, so this cannot fail.
    Header::from_bytes(name.as_bytes(), value.as_bytes()).expect("ASCII header")
}

fn respond(
    status: u16,
    content_type: &str,
    body: impl Read + Send + 'static,
    length: usize,
) -> ResponseBox {
    let headers = vec![
        header("Content-Type", content_type),
        header("Cache-Control", "no-store"),
        header("X-Content-Type-Options", "nosniff"),
        header("Referrer-Policy", "no-referrer"),
    ];
    Response::new(status.into(), headers, body, Some(length), None).boxed()
}

fn text(status: u16, body: &str) -> ResponseBox {
    let body = body.as_bytes().to_vec();
    let length = body.len();
    respond(
        status,
        "text/plain; charset=utf-8",
        Cursor::new(body),
        length,
    )
}

fn route(request: &Request, content: &dyn Content, loopback: bool) -> ResponseBox {
    if loopback && !host_is_loopback(request) {
        return text(403, "this server answers to localhost only\n");
    }
    if *request.method() != Method::Get {
        return text(404, "not found\n");
    }
    let (path, query) = request.url().split_once('?').unwrap_or((request.url(), ""));
    match path {
        "/" => respond(200, "text/html; charset=utf-8", PAGE.as_bytes(), PAGE.len()).with_header(
            header(
                "Content-Security-Policy",
                "default-src 'none'; script-src 'unsafe-inline'; style-src 'unsafe-inline'; \
             connect-src 'self'; img-src 'self' data:; base-uri 'none'; form-action 'none'",
            ),
        ),
        "/state" => match parse_query(query) {
            Some(q) => {
                let body = content.state(q).into_bytes();
                let length = body.len();
                respond(200, "application/json", Cursor::new(body), length)
            }
            None => text(400, "expected /state?since=N&errors=N\n"),
        },
        _ => match path.strip_prefix("/image/").and_then(parse_index) {
            Some(index) => match content.image(index) {
                Some(image) => {
                    let length = image.floats.len();
                    respond(
                        200,
                        "application/octet-stream",
                        Cursor::new(Bytes(image.floats)),
                        length,
                    )
                    .with_header(header("X-Vmerge-Width", &image.width.to_string()))
                    .with_header(header("X-Vmerge-Height", &image.height.to_string()))
                    .with_header(header("X-Vmerge-Iteration", &image.iteration.to_string()))
                }
                None => text(404, "no such image (yet)\n"),
            },
            None => text(404, "not found\n"),
        },
    }
}

/// The image's bytes, shared with the state rather than copied for each request.
struct Bytes(Arc<Vec<u8>>);

impl AsRef<[u8]> for Bytes {
    fn as_ref(&self) -> &[u8] {
        &self.0
    }
}

/// Digits only: no sign, no path, nothing else.
fn parse_index(s: &str) -> Option<usize> {
    if s.is_empty() || !s.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    s.parse().ok()
}

fn parse_query(query: &str) -> Option<StateQuery> {
    let mut q = StateQuery::default();
    for pair in query.split('&').filter(|p| !p.is_empty()) {
        match pair.split_once('=')? {
            ("since", v) => q.since = Some(parse_index(v)? as u64),
            ("errors", v) => q.errors_from = parse_index(v)?,
            _ => return None,
        }
    }
    Some(q)
}

/// Whether the request's `Host` names this machine's loopback (any port: an SSH tunnel may
/// forward another one). A browser always sends it; a page of another site that resolves its
/// own name to 127.0.0.1 sends that name, and is refused.
fn host_is_loopback(request: &Request) -> bool {
    let Some(host) = request
        .headers()
        .iter()
        .find(|h| h.field.equiv("Host"))
        .map(|h| h.value.as_str())
    else {
        return true;
    };
    let name = match host.strip_prefix('[') {
        Some(rest) => rest.split(']').next().unwrap_or(""),
        None => host.rsplit_once(':').map_or(host, |(name, _)| name),
    };
    name.eq_ignore_ascii_case("localhost")
        || name
            .parse::<std::net::IpAddr>()
            .is_ok_and(|ip| ip.is_loopback())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn indices_are_digits_only() {
        assert_eq!(parse_index("12"), Some(12));
        for bad in ["", "+1", "-1", "1/", "../1", "1.0", "0x1", "1 "] {
            assert_eq!(parse_index(bad), None, "{bad:?}");
        }
    }

    #[test]
    fn queries_name_since_and_errors_only() {
        let q = parse_query("since=3&errors=7").unwrap();
        assert_eq!((q.since, q.errors_from), (Some(3), 7));
        let q = parse_query("").unwrap();
        assert_eq!((q.since, q.errors_from), (None, 0));
        for bad in ["file=/etc/passwd", "since=x", "since", "errors=-1"] {
            assert!(parse_query(bad).is_none(), "{bad:?}");
        }
    }
}
