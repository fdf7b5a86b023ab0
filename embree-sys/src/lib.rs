//! Raw bindings to the system Embree.
