//! The exact merge: parts of one render -> the whole render's pixels, or a one-line error
//! naming the parts that differ, the samples that are missing or the samples held twice.

use std::path::{Path, PathBuf};

use super::{PartFile, PartHeader};
use crate::math::{ExactRgb, Vec3};
use crate::render::Rect;
use crate::wavefront::RenderStats;
use crate::{bail, Result};

/// The merged render.
pub struct Merged {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Samples per pixel of the whole render (`-s`).
    pub spp: u32,
    /// Whether the parts were rendered with `-a` (then a rate image goes with the image).
    pub adaptive: bool,
    /// Mean radiance per pixel, row-major, row 0 at the top.
    pub pixels: Vec<Vec3>,
    /// Samples taken per pixel, in the same order.
    pub samples: Vec<u32>,
    /// Statistics summed over the parts, and their rendering times summed.
    pub stats: RenderStats,
    /// The parts' rendering times, summed (seconds).
    pub seconds: f64,
}

/// Merges `parts` (each with the file it came from, for messages).
pub fn merge(parts: &[(PathBuf, PartFile)]) -> Result<Merged> {
    let Some((first_path, first)) = parts.first() else { bail!("merge: no parts given") };
    let (width, height, spp) = image_of(first_path, &first.header)?;
    for (path, p) in &parts[1..] {
        check_same(first_path, &first.header, path, &p.header)?;
    }
    for (path, p) in parts {
        let h = &p.header;
        if h.crop.x1 > width || h.crop.y1 > height || h.samples.end > spp {
            bail!(
                "{}: crop {} or samples {}..{} outside the {width}x{height} image at -s {spp}",
                path.display(),
                h.crop,
                h.samples.start,
                h.samples.end
            );
        }
    }
    check_overlaps(parts)?;
    let n = (width * height) as usize;
    let (mut sums, mut samples) = (vec![ExactRgb::default(); n], vec![0u32; n]);
    let mut covered = vec![0u32; n];
    let mut stats = RenderStats::default();
    let mut seconds = 0.0;
    for (_, p) in parts {
        add_part(p, width, &mut sums, &mut samples, &mut covered);
        stats.add(&p.header.stats);
        seconds += p.header.seconds;
    }
    check_gaps(parts, width, spp, &covered)?;
    let pixels = sums.iter().zip(&samples).map(|(s, &k)| Vec3::from_array(s.mean(k))).collect();
    let adaptive = first.header.flags.contains(" -a ");
    Ok(Merged { width, height, spp, adaptive, pixels, samples, stats, seconds })
}

/// Image size and spp from the header's flags (`-r W H -s N ...`).
fn image_of(path: &Path, h: &PartHeader) -> Result<(u32, u32, u32)> {
    let words: Vec<&str> = h.flags.split(' ').collect();
    let value = |flag: &str, k: usize| -> Option<u32> {
        let i = words.iter().position(|w| *w == flag)?;
        words.get(i + k)?.parse().ok().filter(|&v| v > 0)
    };
    match (value("-r", 1), value("-r", 2), value("-s", 1)) {
        // The renderer's own limits (`-r`): a damaged header cannot ask for terabytes.
        (Some(w), Some(h), Some(s)) if w <= 16_384 && h <= 16_384 && w * h <= 1 << 27 => {
            Ok((w, h, s))
        }
        _ => bail!(
            "{}: part file flags '{}' name no valid image size (-r, at most 16384 a side) and -s",
            path.display(),
            h.flags
        ),
    }
}

fn check_same(a_path: &Path, a: &PartHeader, b_path: &Path, b: &PartHeader) -> Result<()> {
    let (a_name, b_name) = (a_path.display(), b_path.display());
    if a.renderer != b.renderer {
        bail!("merge: {b_name} was rendered by pathtracer {}, {a_name} by {}: re-render one with the other's version", b.renderer, a.renderer);
    }
    if a.scene_hash != b.scene_hash {
        bail!("merge: {b_name} is a part of another scene ({}, hash {:016x}) than {a_name} ({}, hash {:016x})", b.scene, b.scene_hash, a.scene, a.scene_hash);
    }
    if a.flags != b.flags {
        bail!(
            "merge: {b_name} was rendered with other flags than {a_name} ('{}' against '{}')",
            b.flags,
            a.flags
        );
    }
    Ok(())
}

/// Two parts that share pixels must not share samples.
fn check_overlaps(parts: &[(PathBuf, PartFile)]) -> Result<()> {
    for (i, (a_path, a)) in parts.iter().enumerate() {
        for (b_path, b) in &parts[i + 1..] {
            let (a, b) = (&a.header, &b.header);
            let Some(both) = intersect(&a.crop, &b.crop) else { continue };
            let (s0, s1) = (a.samples.start.max(b.samples.start), a.samples.end.min(b.samples.end));
            if s0 < s1 {
                let (a_name, b_name) = (a_path.display(), b_path.display());
                bail!("merge: {a_name} and {b_name} both hold samples {s0}..{s1} of pixels {both}");
            }
        }
    }
    Ok(())
}

fn intersect(a: &Rect, b: &Rect) -> Option<Rect> {
    let r = Rect { x0: a.x0.max(b.x0), y0: a.y0.max(b.y0), x1: a.x1.min(b.x1), y1: a.y1.min(b.y1) };
    (r.x0 < r.x1 && r.y0 < r.y1).then_some(r)
}

fn add_part(
    p: &PartFile,
    width: u32,
    sums: &mut [ExactRgb],
    samples: &mut [u32],
    covered: &mut [u32],
) {
    let c = &p.header.crop;
    let range = p.header.samples.end - p.header.samples.start;
    for (row, y) in (c.y0..c.y1).enumerate() {
        for (col, x) in (c.x0..c.x1).enumerate() {
            let (i, j) = ((y * width + x) as usize, row * c.width() as usize + col);
            sums[i].merge(&p.sums[j]);
            samples[i] += p.counts[j];
            covered[i] += range;
        }
    }
}

/// With no overlaps, a pixel is complete when its parts' sample ranges add up to `spp`.
fn check_gaps(parts: &[(PathBuf, PartFile)], width: u32, spp: u32, covered: &[u32]) -> Result<()> {
    let Some(i) = covered.iter().position(|&c| c != spp) else { return Ok(()) };
    let (x, y) = (i as u32 % width, i as u32 / width);
    let mut held: Vec<_> = parts
        .iter()
        .map(|(_, p)| &p.header)
        .filter(|h| (h.crop.x0..h.crop.x1).contains(&x) && (h.crop.y0..h.crop.y1).contains(&y))
        .map(|h| h.samples.clone())
        .collect();
    held.sort_by_key(|r| r.start);
    let mut next = 0;
    for r in &held {
        if r.start > next {
            break;
        }
        next = r.end;
    }
    let end = held.iter().map(|r| r.start).find(|&s| s > next).unwrap_or(spp);
    bail!(
        "merge: no part holds samples {next}..{end} of pixel ({x}, {y}) (-s {spp}; part files given: {})",
        parts.len()
    )
}
