//! Renders cut into parts for many machines, and the exact merge of the parts.
//!
//! A part is a rectangle of pixels and a range of each pixel's samples (`--crop`, `--samples`,
//! or part K of the deterministic plan of N, `--part K/N`, `plan.rs`). Every sample depends
//! only on (seed, pixel, sample index), and a pixel's radiance is summed exactly
//! (`math::ExactRgb`), so the parts of any plan merged (`merge.rs`) give the same bytes as the
//! whole render. A part is written as a `.ptpart` file (`part_file.rs`): a text header naming
//! the scene (a hash of its bytes), the renderer version, the flags that shape the image, the
//! part's rectangle and samples and its statistics, then the exact per-pixel sums and sample
//! counts, then a checksum. A whole render is the plan of one part.

mod merge;
mod part_file;
mod plan;

pub use merge::{merge, Merged};
pub use part_file::{fnv1a64, read_part, write_part, PartFile, PartHeader, FORMAT};
pub use plan::{plan, plan_part, Part};

use crate::accel::AccelKind;
use crate::render::RenderConfig;

/// The flags that decide a render's pixels, in one canonical form: parts merge only when
/// these are equal. Threads, progress and the output name are not among them.
pub fn image_flags(config: &RenderConfig, accel: AccelKind) -> String {
    let mut s = format!(
        "-r {} {} -s {} -l {} -m {} --shading {} --seed {} --sampler {}",
        config.width,
        config.height,
        config.spp,
        config.light_samples,
        config.max_depth,
        config.integrator.name(),
        config.seed,
        config.sampler.name()
    );
    if let Some((batch, tol)) = config.adaptive {
        s += &format!(" -a {batch} {tol}");
    }
    if config.edge_samples != crate::render::DEFAULT_EDGE_SAMPLES {
        s += &format!(" --edge-samples {}", config.edge_samples);
    }
    if accel == AccelKind::BruteForce {
        s += " --no-bvh";
    }
    s
}
