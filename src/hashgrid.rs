//! Triplet-cell hash grid (000 sec. 2.4.9).
