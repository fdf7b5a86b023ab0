//! A web page for watching a render converge ([`LivePreview`], `vmerge render --preview`) and
//! for looking at finished ones ([`Viewer`], `vmerge view`), served over HTTP.
//!
//! The page tone-maps in the browser from the linear pixels (little-endian f32 RGB), so the
//! server only copies and converts. Safe by default: it binds where it is told (loopback
//! unless an address is given, with a warning for the caller to show otherwise), answers its
//! own routes only (`/`, `/state`, `/image/N`, nothing taken from the request names a file),
//! refuses on loopback any `Host` but a loopback name with the port served (so another site
//! cannot read it through DNS rebinding), lets no stalled client hold up its stopping, and
//! the page loads nothing from the network:
//! its script and style are embedded in the binary and its Content-Security-Policy forbids the
//! rest. The render loop sees it only through [`crate::render::Observer`].

mod live;
mod server;
mod view;

pub use live::LivePreview;
pub use server::{PreviewError, Server};
pub use view::Viewer;

/// The address `--preview` binds to when given none: loopback, a port the system chooses.
pub const DEFAULT_ADDRESS: &str = "127.0.0.1:0";

/// One image the page can fetch as `/image/N`: linear RGB as little-endian f32, row-major.
#[derive(Clone)]
pub(crate) struct ImageData {
    pub width: u32,
    pub height: u32,
    /// The iteration the pixels belong to (0 for a file or a reference).
    pub iteration: u64,
    pub floats: std::sync::Arc<Vec<u8>>,
}

impl ImageData {
    pub fn from_rgb(width: u32, height: u32, iteration: u64, pixels: &[crate::color::Rgb]) -> Self {
        let mut floats = vec![0; pixels.len() * 12];
        for (out, p) in floats.chunks_exact_mut(12).zip(pixels) {
            for (o, c) in out.chunks_exact_mut(4).zip(p.to_array()) {
                o.copy_from_slice(&c.to_le_bytes());
            }
        }
        ImageData {
            width,
            height,
            iteration,
            floats: floats.into(),
        }
    }

    /// The mean image of a film's `sums` after `iterations`.
    pub fn from_sums(width: u32, height: u32, iterations: u64, sums: &[[f64; 3]]) -> Self {
        let scale = 1.0 / iterations.max(1) as f64;
        let mut floats = vec![0; sums.len() * 12];
        for (out, s) in floats.chunks_exact_mut(12).zip(sums) {
            for (o, c) in out.chunks_exact_mut(4).zip(s) {
                o.copy_from_slice(&((c * scale) as f32).to_le_bytes());
            }
        }
        ImageData {
            width,
            height,
            iteration: iterations,
            floats: floats.into(),
        }
    }
}

/// The error series of a render as the page's chart reads it: `[seconds, iterations, mae, rmse]`.
pub(crate) fn error_rows(errors: &[crate::film::ErrorSample]) -> Vec<[f64; 4]> {
    errors
        .iter()
        .map(|e| [e.seconds, e.iterations as f64, e.mae, e.rmse])
        .collect()
}
