//! Render driver (to be written).
