//! Stage 2: closest-hit queries for every queued ray.

use super::super::{RayQueue, RenderContext};
use crate::accel::TraceStats;
use crate::math::Hit;

/// How a queue's rays are traced. Camera rays of a tile (and their shadow rays) are coherent:
/// neighbouring queue entries are samples of the same or adjacent pixels, so 8-wide packets
/// share most nodes. The first bounce still starts from neighbouring points, and on a
/// cache-resident structure packets win there too; later bounces scatter and go one at a
/// time, in streams. Packet and single-ray traversal return bit-identical hits, so the choice
/// never changes the image.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Coherence {
    Coherent,
    Incoherent,
}

impl Coherence {
    /// Camera rays (depth 0) are coherent, and first bounces (depth 1) unless the structure
    /// outgrows the caches (measured: PERF.md, "Measurements moved from doc comments").
    /// `packets: false` treats every queue as incoherent (single rays throughout).
    pub fn of_depth(depth: u32, packets: bool, large_structure: bool) -> Coherence {
        if packets && (depth == 0 || (depth == 1 && !large_structure)) {
            Coherence::Coherent
        } else {
            Coherence::Incoherent
        }
    }
}

/// Packet width for coherent queues.
pub const PACKET: usize = 8;

/// Finds the closest hit of each queued ray; `hits[i]` answers `rays.rays[i]`.
pub fn extend(
    ctx: &RenderContext,
    rays: &RayQueue,
    coherence: Coherence,
    hits: &mut Vec<Option<Hit>>,
    stats: &mut TraceStats,
) {
    hits.clear();
    match coherence {
        Coherence::Coherent => {
            hits.resize(rays.len(), None);
            ctx.accel.intersect_packets::<PACKET>(&rays.rays, hits, stats);
        }
        Coherence::Incoherent => {
            hits.resize(rays.len(), None);
            ctx.accel.intersect_stream(&rays.rays, hits, stats);
        }
    }
}
