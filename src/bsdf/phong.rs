//! phong
