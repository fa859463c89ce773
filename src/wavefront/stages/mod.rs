//! One file per stage; `wavefront::trace_sample_batch` calls them in order.

mod accumulate;
mod extend;
mod generate;
mod shade;
mod shadow;

pub use accumulate::accumulate;
pub use extend::{drop_misses, extend, extend_to_emitters, Coherence, EmitterScratch};
pub use generate::{emitter_window, generate_camera_rays, mark_emitter_edges, EdgePixels};
pub use shade::{group_specular, shade, ShadeScratch};
pub use shadow::{trace_emission_probes, trace_shadow_rays};
