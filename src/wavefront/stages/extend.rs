//! Stage 2: closest-hit queries for every queued ray.

use super::super::{RayQueue, RenderContext};
use crate::accel::TraceStats;
use crate::math::Hit;

/// Finds the closest hit of each queued ray; `hits[i]` answers `rays.rays[i]`.
pub fn extend(
    ctx: &RenderContext,
    rays: &RayQueue,
    hits: &mut Vec<Option<Hit>>,
    stats: &mut TraceStats,
) {
    hits.clear();
    hits.extend(rays.rays.iter().map(|r| ctx.accel.intersect(r, stats)));
}
