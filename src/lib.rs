//! vmerge: a physically based CPU renderer implementing path tracing, bidirectional path
//! tracing, vertex connection and merging and unbiased photon gathering.
//!
//! Equations are cited by source document and number, e.g. `001 eq. (35)`: 000 is Ciechowski's
//! thesis on VCM and UPG, 001 Georgiev's "Implementing Vertex Connection and Merging", 002
//! Jendersie and Grosch's improved MIS heuristic, 003 a GPU VCM thesis, 004 a BDPM thesis.

pub mod accel;
pub mod bsdf;
pub mod color;
pub mod files;
pub mod film;
pub mod frame;
pub mod hashgrid;
pub mod integrator;
pub mod light;
pub mod memory;
pub mod metrics;
pub mod options;
pub mod prefetch;
pub mod preview;
pub mod render;
pub mod sampling;
pub mod scene;
pub mod texture;
pub mod tools;
