//! Deterministic procedural scenes (to be written).
