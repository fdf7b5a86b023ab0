//! lambert
