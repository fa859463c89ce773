//! The render driver: scene + accel + config -> linear image, with statistics and progress.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use rayon::prelude::*;

use crate::accel::Accel;
use crate::integrator::Integrator;
use crate::math::Vec3;
use crate::sampler::SamplerKind;
use crate::scene::{Camera, Scene};
use crate::wavefront::{self, RenderContext, RenderStats, Tile, Workspace};

/// Everything a render needs besides the scene, with the course's defaults.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderConfig {
    pub width: u32,
    pub height: u32,
    /// Samples per pixel (`-s`).
    pub spp: u32,
    /// Samples per area light (`-l`).
    pub light_samples: u32,
    /// Maximum ray depth (`-m`).
    pub max_depth: u32,
    /// Adaptive sampling (`-a batch tolerance`).
    pub adaptive: Option<(u32, f32)>,
    /// Worker threads (`-t`); 0 = all cores.
    pub threads: usize,
    pub seed: u64,
    /// How random numbers are drawn (`--sampler`).
    pub sampler: SamplerKind,
    pub integrator: Integrator,
    /// Print a progress line on stderr for renders longer than a second.
    pub progress: bool,
    /// An explicit camera instead of the course's bounding-box framing (for tests and tools
    /// that need a view the course camera cannot give, such as one inside closed geometry).
    pub camera: Option<Camera>,
    /// Trace coherent queues (camera rays and their shadow rays) in 8-wide packets; `false`
    /// traces every ray alone. Both give bit-identical images (tests/traversal_agree.rs).
    pub packets: bool,
}

impl Default for RenderConfig {
    fn default() -> Self {
        RenderConfig {
            width: 800,
            height: 600,
            spp: 1,
            light_samples: 1,
            max_depth: 1,
            adaptive: None,
            threads: 0,
            seed: 0,
            sampler: SamplerKind::default(),
            integrator: Integrator::Normals,
            progress: false,
            camera: None,
            packets: true,
        }
    }
}

/// A rendered image (linear radiance, row-major, row 0 at the top) and how it was made.
pub struct RenderOutput {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<Vec3>,
    /// Samples taken by each pixel (all equal to `spp` unless adaptive sampling stopped early).
    pub samples: Vec<u32>,
    pub stats: RenderStats,
    pub time: Duration,
}

/// Renders `scene` through `accel` as `config` says.
pub fn render(scene: &Scene, accel: &Accel, config: &RenderConfig) -> crate::Result<RenderOutput> {
    let bounds = scene.bounds();
    let camera = match config.camera {
        Some(c) if (c.width, c.height) == (config.width, config.height) => c,
        Some(c) => crate::bail!(
            "camera is for {}x{}, image is {}x{}",
            c.width,
            c.height,
            config.width,
            config.height
        ),
        None => Camera::new(&scene.camera, bounds, config.width, config.height),
    };
    let lights = config.integrator.light_set(scene);
    let ctx = RenderContext {
        scene,
        accel,
        camera: &camera,
        integrator: &config.integrator,
        lights: &lights,
        spp: config.spp,
        light_samples: config.light_samples,
        max_depth: config.max_depth,
        adaptive: config.adaptive,
        seed: config.seed,
        sampler: config.sampler,
        packets: config.packets,
        scene_epsilon: 1e-5 * bounds.diagonal().max(f32::MIN_POSITIVE),
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(config.threads)
        .build()
        .map_err(|e| crate::Error::new(format!("cannot start {} threads: {e}", config.threads)))?;
    // The image buffers first, so that an image too large for memory is an error before any
    // work, and each tile is copied in as it finishes (never the whole image twice).
    let n = config.width as usize * config.height as usize;
    let size = format!("the {}x{} image", config.width, config.height);
    let image = Mutex::new(Image {
        pixels: crate::error::try_filled_vec(n, Vec3::ZERO, &size)?,
        samples: crate::error::try_filled_vec(n, 0, &size)?,
        stats: RenderStats::default(),
    });
    let tiles = wavefront::tiles(config.width, config.height);
    let done = AtomicUsize::new(0);
    let start = Instant::now();
    let time = std::thread::scope(|s| {
        // A progress line only makes sense on a terminal; logs and pipes get the final stats.
        if config.progress && std::io::IsTerminal::is_terminal(&std::io::stderr()) {
            s.spawn(|| report_progress(&done, tiles.len(), start));
        }
        pool.install(|| {
            tiles.par_iter().for_each_init(Workspace::default, |ws, &tile| {
                let r = render_one_tile(&ctx, tile, ws);
                image.lock().unwrap_or_else(|e| e.into_inner()).add_tile(config.width, &tile, &r);
                done.fetch_add(1, Ordering::Relaxed);
            })
        });
        let time = start.elapsed();
        done.store(usize::MAX, Ordering::Relaxed);
        time
    });
    let Image { pixels, samples, stats } = image.into_inner().unwrap_or_else(|e| e.into_inner());
    Ok(RenderOutput { width: config.width, height: config.height, pixels, samples, stats, time })
}

/// The image being assembled from finished tiles.
struct Image {
    pixels: Vec<Vec3>,
    samples: Vec<u32>,
    stats: RenderStats,
}

impl Image {
    fn add_tile(&mut self, width: u32, tile: &Tile, r: &TileResult) {
        copy_tile(&mut self.pixels, width, tile, &r.pixels);
        copy_tile(&mut self.samples, width, tile, &r.samples);
        // Integer counts: the sum does not depend on the order tiles finish in.
        self.stats.add(&r.stats);
    }
}

struct TileResult {
    pixels: Vec<Vec3>,
    samples: Vec<u32>,
    stats: RenderStats,
}

fn render_one_tile(ctx: &RenderContext, tile: Tile, ws: &mut Workspace) -> TileResult {
    let mut r = TileResult {
        pixels: vec![Vec3::ZERO; tile.pixel_count()],
        samples: vec![0; tile.pixel_count()],
        stats: RenderStats::default(),
    };
    wavefront::render_tile(ctx, tile, ws, &mut r.pixels, &mut r.samples, &mut r.stats);
    r
}

fn copy_tile<T: Copy>(image: &mut [T], image_width: u32, tile: &Tile, tile_pixels: &[T]) {
    for row in 0..tile.height {
        let src = &tile_pixels[(row * tile.width) as usize..((row + 1) * tile.width) as usize];
        let dst_start = ((tile.y0 + row) * image_width + tile.x0) as usize;
        image[dst_start..dst_start + tile.width as usize].copy_from_slice(src);
    }
}

/// Prints "Rendering... NN%" on stderr a few times a second once the render has run a second;
/// stops when `done` is set to `usize::MAX`.
fn report_progress(done: &AtomicUsize, total: usize, start: Instant) {
    use std::io::Write;
    let mut printed = false;
    let mut last_print = start;
    loop {
        std::thread::sleep(Duration::from_millis(10));
        let d = done.load(Ordering::Relaxed);
        if d == usize::MAX {
            break;
        }
        if start.elapsed() > Duration::from_secs(1)
            && last_print.elapsed() > Duration::from_millis(250)
        {
            last_print = Instant::now();
            let pct = 100 * d / total.max(1);
            // Never `eprint!`, which panics if the terminal is gone.
            let mut stderr = std::io::stderr().lock();
            let secs = start.elapsed().as_secs_f64();
            let _ = write!(stderr, "\r[PathTracer] Rendering... {pct:3}% ({secs:.1}s)");
            let _ = stderr.flush();
            printed = true;
        }
    }
    if printed {
        let _ = write!(std::io::stderr(), "\r\x1b[2K");
    }
}
