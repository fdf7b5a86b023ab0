//! Random numbers and the warps that turn them into directions, points and choices.

mod distribution;
mod rng;
mod sampler;
mod warp;

pub use distribution::{Distribution1D, Distribution2D};
pub use rng::{Rng, Stream};
pub use sampler::Sampler;
pub use warp::*;
