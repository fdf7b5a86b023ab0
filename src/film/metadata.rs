//! What vmerge records about a render next to its pixels: the technique and every option, the
//! scene and its hash, the seed, iterations, time, dropped samples, statistics and the error
//! series against a reference (000 sec. 3.4). Stored as one TOML document in an EXR text
//! attribute, so any EXR header dump shows it.

use crate::render::RenderOptions;
use serde::{Deserialize, Serialize};

/// A square error window of `000 Appendix A`'s `--trace=XxYxW`: centre (x, y), half-width w.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct TraceWindow {
    pub x: u32,
    pub y: u32,
    pub half_width: u32,
}

impl TraceWindow {
    /// Pixel rectangle `[x0, x1) x [y0, y1)` clipped to the image.
    pub fn rect(&self, width: u32, height: u32) -> (u32, u32, u32, u32) {
        let x0 = self.x.saturating_sub(self.half_width).min(width);
        let y0 = self.y.saturating_sub(self.half_width).min(height);
        let x1 = (self.x + self.half_width).min(width);
        let y1 = (self.y + self.half_width).min(height);
        (x0, y0, x1, y1)
    }
}

impl std::str::FromStr for TraceWindow {
    type Err = String;

    /// `XxY` or `XxYxW` (W defaults to 2, as in 000 Appendix A).
    fn from_str(s: &str) -> Result<Self, String> {
        let parts: Vec<u32> = s
            .split('x')
            .map(|p| p.trim().parse::<u32>())
            .collect::<Result<_, _>>()
            .map_err(|_| format!("'{s}' is not XxY or XxYxW (non-negative integers)"))?;
        match parts[..] {
            [x, y] => Ok(TraceWindow {
                x,
                y,
                half_width: 2,
            }),
            [x, y, w] if w > 0 => Ok(TraceWindow {
                x,
                y,
                half_width: w,
            }),
            _ => Err(format!("'{s}' is not XxY or XxYxW with W > 0")),
        }
    }
}

/// Errors of the image against the reference at one moment.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ErrorSample {
    pub seconds: f64,
    pub iterations: u64,
    /// Mean absolute error over all pixels and channels.
    pub mae: f64,
    /// Root-mean-square error over all pixels and channels.
    pub rmse: f64,
    /// `(mae, rmse)` of each trace window, in the order of `Metadata::traces`.
    #[serde(default)]
    pub traces: Vec<[f64; 2]>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Metadata {
    pub vmerge_version: String,
    /// The scene file as given, and the canonical path used by `continue`.
    pub scene: String,
    pub scene_hash: String,
    pub options: RenderOptions,
    pub accel: String,
    pub iterations: u64,
    pub render_seconds: f64,
    pub dropped_samples: u64,
    #[serde(default)]
    pub statistics: Vec<(String, String)>,
    /// Reference image the errors were measured against.
    #[serde(default)]
    pub reference: Option<String>,
    #[serde(default)]
    pub traces: Vec<TraceWindow>,
    #[serde(default)]
    pub errors: Vec<ErrorSample>,
}

impl Metadata {
    pub fn new(scene: String, scene_hash: String, options: RenderOptions, accel: &str) -> Self {
        Metadata {
            vmerge_version: env!("CARGO_PKG_VERSION").to_string(),
            scene,
            scene_hash,
            options,
            accel: accel.to_string(),
            iterations: 0,
            render_seconds: 0.0,
            dropped_samples: 0,
            statistics: Vec::new(),
            reference: None,
            traces: Vec::new(),
            errors: Vec::new(),
        }
    }

    pub fn to_toml(&self) -> Result<String, String> {
        toml::to_string(self).map_err(|e| e.to_string())
    }

    pub fn from_toml(text: &str) -> Result<Self, String> {
        toml::from_str(text).map_err(|e| e.to_string())
    }
}
