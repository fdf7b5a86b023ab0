//! Unbiased photon gathering (000 sec. 2.4.3): merges whose acceptance probability is estimated.

pub mod acceptance;
