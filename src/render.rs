//! The render driver: scene + accel + config -> linear image, with statistics and progress.

use std::ops::Range;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use rayon::prelude::*;

use crate::accel::Accel;
use crate::integrator::{EmitterAccel, Integrator};
use crate::math::{ExactRgb, Vec3};
use crate::sampler::SamplerKind;
use crate::scene::{Camera, Scene};
use crate::wavefront::{self, RenderContext, RenderStats, StageTimes, Tile, Workspace};

/// Extra camera rays per sample on emitter outlines unless `--edge-samples` says otherwise
/// (PERF.md, "Whole renders": the noise they remove against the rays they cost).
pub const DEFAULT_EDGE_SAMPLES: u32 = 8;

/// Everything a render needs besides the scene, with the course's defaults.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderConfig {
    /// Image width in pixels (`-r`).
    pub width: u32,
    /// Image height in pixels (`-r`).
    pub height: u32,
    /// Samples per pixel (`-s`).
    pub spp: u32,
    /// Samples per area light (`-l`).
    pub light_samples: u32,
    /// Extra camera rays per sample on the outlines of visible emitters (`--edge-samples`),
    /// which share the estimate of the emission the camera sees there; 0: none.
    pub edge_samples: u32,
    /// Maximum ray depth (`-m`).
    pub max_depth: u32,
    /// Adaptive sampling (`-a batch tolerance`).
    pub adaptive: Option<(u32, f32)>,
    /// Only these samples of each pixel (a part of a farm render, `--samples A..B`); `None`:
    /// all of `0..spp`. Sample `i` is the same wherever it is rendered.
    pub samples: Option<Range<u32>>,
    /// Only these pixels (`--crop`); `None`: the whole image. Other pixels stay black.
    pub crop: Option<Rect>,
    /// Return the exact per-pixel sums of the rendered pixels (`RenderOutput::sums`).
    pub keep_sums: bool,
    /// Worker threads (`-t`); 0 = all cores.
    pub threads: usize,
    /// Seed of the random numbers, which depend only on (seed, pixel, sample): the same seed
    /// gives the same image whatever the thread count.
    pub seed: u64,
    /// How random numbers are drawn (`--sampler`).
    pub sampler: SamplerKind,
    /// What a sample computes: normal shading, or direct lighting / path tracing.
    pub integrator: Integrator,
    /// Print a progress line on stderr for renders longer than a second.
    pub progress: bool,
    /// An explicit camera instead of the course's bounding-box framing (for tests and tools
    /// that need a view the course camera cannot give, such as one inside closed geometry).
    pub camera: Option<Camera>,
    /// Trace coherent queues (camera rays and their shadow rays) in 8-wide packets; `false`
    /// traces every ray alone. Both give bit-identical images (tests/traversal_agree.rs).
    pub packets: bool,
    /// Shade surface vertices in SIMD lanes (`integrator::diffuse`); `false` shades every
    /// vertex alone. Both give bit-identical images (tests/lighting.rs).
    pub shading_lanes: bool,
    /// Rays that can only add emission look for the emitters first (`integrator::EmitterAccel`);
    /// `false` traces them as other rays. Both give bit-identical images unless an emitter and
    /// another surface coincide exactly (tests/emitters_first.rs).
    pub emitters_first: bool,
    /// Under light sampling and MIS, glossy vertices weigh their area-light samples against
    /// their BSDF sample (`integrator` `path::weighs_area_lights`); `false` keeps plain light
    /// sampling. Both converge to the same image (tests/glossy_mis.rs).
    pub glossy_light_mis: bool,
    /// Time each stage of the render loop (`RenderOutput::stage_times`, `--stage-times`);
    /// `false` leaves the clock unread and the times zero.
    pub stage_times: bool,
}

impl Default for RenderConfig {
    fn default() -> Self {
        RenderConfig {
            width: 800,
            height: 600,
            spp: 1,
            light_samples: 1,
            edge_samples: DEFAULT_EDGE_SAMPLES,
            max_depth: 1,
            adaptive: None,
            samples: None,
            crop: None,
            keep_sums: false,
            threads: 0,
            seed: 0,
            sampler: SamplerKind::default(),
            integrator: Integrator::Normals,
            progress: false,
            camera: None,
            packets: true,
            shading_lanes: true,
            glossy_light_mis: true,
            emitters_first: true,
            stage_times: false,
        }
    }
}

/// A pixel rectangle `x0..x1` x `y0..y1` (ends excluded), row 0 at the top.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Rect {
    /// First column.
    pub x0: u32,
    /// First row.
    pub y0: u32,
    /// Column past the last.
    pub x1: u32,
    /// Row past the last.
    pub y1: u32,
}

impl Rect {
    /// The whole `width` x `height` image.
    pub fn of_image(width: u32, height: u32) -> Rect {
        Rect { x0: 0, y0: 0, x1: width, y1: height }
    }

    /// Columns in the rectangle.
    pub fn width(&self) -> u32 {
        self.x1 - self.x0
    }

    /// Rows in the rectangle.
    pub fn height(&self) -> u32 {
        self.y1 - self.y0
    }

    /// Pixels in the rectangle.
    pub fn pixel_count(&self) -> usize {
        self.width() as usize * self.height() as usize
    }

    /// The part of `tile` inside this rectangle, if any.
    fn clip(&self, t: Tile) -> Option<Tile> {
        let (x0, y0) = (t.x0.max(self.x0), t.y0.max(self.y0));
        let (x1, y1) = ((t.x0 + t.width).min(self.x1), (t.y0 + t.height).min(self.y1));
        (x0 < x1 && y0 < y1).then_some(Tile { x0, y0, width: x1 - x0, height: y1 - y0 })
    }
}

impl std::fmt::Display for Rect {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "({}, {})-({}, {})", self.x0, self.y0, self.x1, self.y1)
    }
}

/// A rendered image (linear radiance, row-major, row 0 at the top) and how it was made.
pub struct RenderOutput {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// `width * height` linear RGB values (black outside the window).
    pub pixels: Vec<Vec3>,
    /// Samples taken by each pixel (all equal to `spp` unless adaptive sampling stopped early).
    pub samples: Vec<u32>,
    /// The pixels rendered: the crop, or the whole image.
    pub window: Rect,
    /// The exact radiance sums of the window's pixels, row-major (with `keep_sums`; else empty).
    pub sums: Vec<ExactRgb>,
    /// Rays and work counted over the render.
    pub stats: RenderStats,
    /// Thread time in each stage of the loop, over all threads (zero unless
    /// `RenderConfig::stage_times`).
    pub stage_times: StageTimes,
    /// Wall time of the render loop (not the setup before it).
    pub time: Duration,
    /// The emitters' own tree (`integrator::EmitterAccel`), where the render built one: its
    /// primitives and build time, part of the setup that `time` leaves out.
    pub emitter_tree: Option<(usize, Duration)>,
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
    if !camera.is_finite() {
        let corner = |v: Vec3| format!("[{:.3e}, {:.3e}, {:.3e}]", v.x, v.y, v.z);
        crate::bail!(
            "cannot place the camera: the scene's bounding box ({} to {}) is too large for \
             32-bit floats",
            corner(bounds.min),
            corner(bounds.max)
        );
    }
    let (samples, window) = check_range_and_crop(config)?;
    let lights = config.integrator.light_set(scene);
    let triangle_normals = scene.triangle_normals()?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(config.threads)
        .build()
        .map_err(|e| crate::Error::new(format!("cannot start {} threads: {e}", config.threads)))?;
    // Only path tracing traces rays that can only add emission. Built in the render's own
    // pool, as its threads are counted: a tree of at most a quarter of the scene's primitives,
    // a few for the course's lights.
    let emitters_start = Instant::now();
    let emitters = (config.emitters_first && matches!(config.integrator, Integrator::Path(_)))
        .then(|| pool.install(|| EmitterAccel::for_scene(scene)))
        .flatten();
    let emitter_tree = emitters.as_ref().map(|e| (e.primitive_count(), emitters_start.elapsed()));
    let ctx = RenderContext {
        scene,
        triangle_normals: &triangle_normals,
        accel,
        emitters: emitters.as_ref(),
        camera: &camera,
        integrator: &config.integrator,
        lights: &lights,
        spp: config.spp,
        samples,
        light_samples: config.light_samples,
        edge_samples: config.edge_samples,
        emitter_window: edge_samples_apply(config)
            .then(|| wavefront::emitter_window(scene, &camera))
            .flatten(),
        max_depth: config.max_depth,
        adaptive: config.adaptive,
        seed: config.seed,
        sampler: config.sampler,
        packets: config.packets,
        shading_lanes: config.shading_lanes,
        glossy_light_mis: config.glossy_light_mis,
        stage_times: config.stage_times,
        mixes_specular: scene.mixes_specular(),
        scene_epsilon: 1e-5 * bounds.diagonal().max(f32::MIN_POSITIVE),
    };
    // The image buffers first, so that an image too large for memory is an error before any
    // work, and each tile is copied in as it finishes (never the whole image twice).
    let n = config.width as usize * config.height as usize;
    let size = format!("the {}x{} image", config.width, config.height);
    let kept = if config.keep_sums { window.pixel_count() } else { 0 };
    let image = Mutex::new(Image {
        pixels: crate::error::try_filled_vec(n, Vec3::ZERO, &size)?,
        samples: crate::error::try_filled_vec(n, 0, &size)?,
        sums: crate::error::try_filled_vec(kept, ExactRgb::default(), &size)?,
        window,
        stats: RenderStats::default(),
        stage_times: StageTimes::default(),
    });
    let tiles: Vec<Tile> = wavefront::tiles(config.width, config.height)
        .into_iter()
        .filter_map(|t| window.clip(t))
        .collect();
    let done = AtomicUsize::new(0);
    let start = Instant::now();
    let time = std::thread::scope(|s| {
        // A progress line only makes sense on a terminal; logs and pipes get the final stats.
        if config.progress && std::io::IsTerminal::is_terminal(&std::io::stderr()) {
            s.spawn(|| report_progress(&done, tiles.len(), start));
        }
        // One rayon job per tile, so that a thread that runs out of tiles takes the next one
        // from another's share: with rayon's default splitting, a thread left holding a run of
        // expensive tiles kept them while the other idled. Each pool thread keeps its own
        // workspace (its queues keep their capacity from tile to tile), behind a lock that no
        // other thread takes.
        let workspaces: Vec<Mutex<Workspace>> =
            (0..pool.current_num_threads()).map(|_| Mutex::default()).collect();
        pool.install(|| {
            tiles.par_iter().with_max_len(1).for_each(|&tile| {
                let slot = rayon::current_thread_index().unwrap_or(0) % workspaces.len();
                // A busy slot (a tile job nested in another on this thread) or a poisoned one
                // gets a fresh workspace: it is scratch space, so the tile is the same.
                let r = match workspaces[slot].try_lock() {
                    Ok(mut ws) => render_one_tile(&ctx, tile, &mut ws),
                    Err(_) => render_one_tile(&ctx, tile, &mut Workspace::default()),
                };
                image.lock().unwrap_or_else(|e| e.into_inner()).add_tile(config.width, &tile, &r);
                done.fetch_add(1, Ordering::Relaxed);
            })
        });
        let time = start.elapsed();
        done.store(usize::MAX, Ordering::Relaxed);
        time
    });
    let Image { pixels, samples, sums, stats, stage_times, .. } =
        image.into_inner().unwrap_or_else(|e| e.into_inner());
    let (width, height) = (config.width, config.height);
    Ok(RenderOutput {
        width,
        height,
        pixels,
        samples,
        window,
        sums,
        stats,
        stage_times,
        time,
        emitter_tree,
    })
}

/// Whether a render takes extra camera rays on emitter outlines at all: a path integrator,
/// more than one sample per pixel (one goes through the centre) and `--edge-samples` above 0.
fn edge_samples_apply(config: &RenderConfig) -> bool {
    config.edge_samples > 0 && config.spp > 1 && config.integrator.direct_lighting().is_some()
}

/// The sample range and the pixel window of `config`, checked against the image and `-s`.
fn check_range_and_crop(config: &RenderConfig) -> crate::Result<(Range<u32>, Rect)> {
    let image = Rect::of_image(config.width, config.height);
    let samples = config.samples.clone().unwrap_or(0..config.spp);
    if samples.start >= samples.end || samples.end > config.spp {
        crate::bail!(
            "samples {}..{}: expected a non-empty range within 0..{} (-s {})",
            samples.start,
            samples.end,
            config.spp,
            config.spp
        );
    }
    if config.adaptive.is_some() && samples != (0..config.spp) {
        crate::bail!(
            "samples {}..{}: adaptive sampling (-a) decides per pixel how many samples to take, \
             so it cannot render a range of them (split the image, not the samples)",
            samples.start,
            samples.end
        );
    }
    let window = config.crop.unwrap_or(image);
    if window.x0 >= window.x1
        || window.y0 >= window.y1
        || window.x1 > image.x1
        || window.y1 > image.y1
    {
        crate::bail!(
            "crop {window}: expected a non-empty rectangle within the {}x{} image",
            config.width,
            config.height
        );
    }
    Ok((samples, window))
}

/// The image being assembled from finished tiles.
struct Image {
    pixels: Vec<Vec3>,
    samples: Vec<u32>,
    /// The exact sums of the pixels in `window`, when the config keeps them (parts).
    sums: Vec<ExactRgb>,
    window: Rect,
    stats: RenderStats,
    stage_times: StageTimes,
}

impl Image {
    fn add_tile(&mut self, width: u32, tile: &Tile, r: &TileResult) {
        let means: Vec<Vec3> =
            r.sums.iter().zip(&r.samples).map(|(s, &n)| Vec3::from_array(s.mean(n))).collect();
        copy_tile(&mut self.pixels, width, tile, &means);
        copy_tile(&mut self.samples, width, tile, &r.samples);
        if !self.sums.is_empty() {
            let w = self.window;
            let local = Tile { x0: tile.x0 - w.x0, y0: tile.y0 - w.y0, ..*tile };
            copy_tile(&mut self.sums, w.width(), &local, &r.sums);
        }
        // Integer counts: the sum does not depend on the order tiles finish in.
        self.stats.add(&r.stats);
        self.stage_times.add(&r.stage_times);
    }
}

struct TileResult {
    sums: Vec<ExactRgb>,
    samples: Vec<u32>,
    stats: RenderStats,
    stage_times: StageTimes,
}

fn render_one_tile(ctx: &RenderContext, tile: Tile, ws: &mut Workspace) -> TileResult {
    let mut r = TileResult {
        sums: vec![ExactRgb::default(); tile.pixel_count()],
        samples: vec![0; tile.pixel_count()],
        stats: RenderStats::default(),
        stage_times: StageTimes::default(),
    };
    wavefront::render_tile(ctx, tile, ws, &mut r.sums, &mut r.samples, &mut r.stats);
    r.stage_times = ws.take_times();
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sample_ranges_and_crops_are_checked() {
        let config = RenderConfig { width: 64, height: 48, spp: 8, ..RenderConfig::default() };
        let check = |f: &dyn Fn(&mut RenderConfig)| {
            let mut c = config.clone();
            f(&mut c);
            check_range_and_crop(&c).map_err(|e| e.to_string())
        };
        assert_eq!(check(&|_| {}), Ok((0..8, Rect::of_image(64, 48))));
        let crop = Rect { x0: 16, y0: 8, x1: 64, y1: 9 };
        assert_eq!(check(&|c| c.crop = Some(crop)), Ok((0..8, crop)));
        assert!(check(&|c| c.samples = Some(3..9)).unwrap_err().contains("within 0..8"));
        assert!(check(&|c| c.samples = Some(3..3)).is_err());
        let wide = Rect { x0: 0, y0: 0, x1: 65, y1: 1 };
        assert!(check(&|c| c.crop = Some(wide)).unwrap_err().contains("crop (0, 0)-(65, 1)"));
        let adaptive_range = |c: &mut RenderConfig| {
            c.adaptive = Some((4, 0.1));
            c.samples = Some(0..4);
        };
        assert!(check(&adaptive_range).unwrap_err().contains("adaptive"));
        let tile = Tile { x0: 0, y0: 0, width: 16, height: 16 };
        assert_eq!(crop.clip(tile), None);
        let inside = Tile { x0: 16, y0: 0, width: 16, height: 16 };
        assert_eq!(crop.clip(inside), Some(Tile { x0: 16, y0: 8, width: 16, height: 1 }));
    }
}
