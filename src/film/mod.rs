//! The film: a finished render (linear radiance per pixel) becomes an image file.
//!
//! - `.png`: the course's tone map, clamp((sqrt(2) L)^(1/2.2), 0, 1) per channel
//!   (SCENE_FORMAT.md "Output"), 8 bits.
//! - `.exr`: linear radiance as 32-bit floats, for comparisons against references.
//! - The adaptive-sampling rate image: samples taken / samples allowed as a colour ramp.
//!
//! Every file is written to a temporary name beside its destination and renamed into place
//! only when complete, so a failed or interrupted write never leaves a half-written image.

mod output;

pub(crate) use output::write_atomically;
pub use output::{rate_image_path, stage_image, stage_rate_image, write_image};
