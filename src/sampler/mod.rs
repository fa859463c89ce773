//! Random numbers. Every stream is derived from (seed, pixel, sample) so that an image does not
//! depend on the thread count or the order in which work is scheduled.

mod pcg32;

pub use pcg32::{splitmix64, Pcg32};
