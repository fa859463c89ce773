//! The `.ptpart` file: one part of a render, exact.
//!
//! ```text
//! pathtracer-part 1                      format line
//! renderer 0.1.0                         the renderer's version
//! scene cornell.dae                      the scene's file name (for messages)
//! scene-fnv1a64 8c1d...                  FNV-1a 64 of the scene file's bytes
//! flags -r 64 48 -s 8 -l 1 ...           `image_flags`: what decides the pixels
//! crop 0 16 64 32                        the pixels x0 y0 x1 y1 (ends excluded)
//! samples 0 8                            the samples A B of each pixel (B excluded)
//! stats 3072 0 3072 0 0 6144 81920 9000 0   camera bounce shadow probe lane-vertices, then
//!                                        traced rays, node, triangle and sphere tests
//! seconds 0.0123                         rendering time
//! end
//! ```
//!
//! then, for each pixel of the crop row by row, 64 bytes little-endian: the sample count
//! (u32), the exact sums (3 x i128, `math::ExactRgb::fixed`) and the non-finite sums (3 x
//! f32); and last the FNV-1a 64 of everything before it (8 bytes), so a truncated or damaged
//! file is refused. Written to a temporary name and renamed, like every image.

use std::ops::Range;
use std::path::Path;

use crate::accel::TraceStats;
use crate::math::ExactRgb;
use crate::render::Rect;
use crate::wavefront::RenderStats;
use crate::{bail, Error, Result};

/// The format line.
pub const FORMAT: &str = "pathtracer-part 1";
const PIXEL_BYTES: usize = 64;

/// What a part is: everything but its pixels.
#[derive(Debug, Clone, PartialEq)]
pub struct PartHeader {
    /// The version of the renderer that wrote the part.
    pub renderer: String,
    /// The scene's file name (for messages).
    pub scene: String,
    /// FNV-1a 64 of the scene file's bytes: parts of different scenes never merge.
    pub scene_hash: u64,
    /// `farm::image_flags` of the render.
    pub flags: String,
    /// The pixels of the part.
    pub crop: Rect,
    /// The samples of each pixel the part holds (end excluded).
    pub samples: Range<u32>,
    /// The part's render statistics.
    pub stats: RenderStats,
    /// The part's rendering time in seconds.
    pub seconds: f64,
}

/// A part: its header, and per pixel of its crop the sample count and exact radiance sum.
#[derive(Debug, Clone, PartialEq)]
pub struct PartFile {
    /// Everything but the pixels.
    pub header: PartHeader,
    /// Samples taken per pixel of the crop, row by row.
    pub counts: Vec<u32>,
    /// Exact radiance sum per pixel of the crop, in the same order.
    pub sums: Vec<ExactRgb>,
}

/// FNV-1a, 64 bits.
pub fn fnv1a64(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| (h ^ b as u64).wrapping_mul(0x100_0000_01b3))
}

/// Writes `part` to `path` (through a temporary name).
pub fn write_part(path: &Path, part: &PartFile) -> Result<()> {
    let n = part.header.crop.pixel_count();
    if part.counts.len() != n || part.sums.len() != n {
        bail!(
            "{}: {} pixels do not fill the crop {}",
            path.display(),
            part.sums.len(),
            part.header.crop
        );
    }
    let mut bytes = header_text(&part.header).into_bytes();
    bytes.reserve(n * PIXEL_BYTES + 8);
    for (count, sum) in part.counts.iter().zip(&part.sums) {
        bytes.extend_from_slice(&count.to_le_bytes());
        sum.fixed.iter().for_each(|v| bytes.extend_from_slice(&v.to_le_bytes()));
        sum.special.iter().for_each(|v| bytes.extend_from_slice(&v.to_le_bytes()));
    }
    bytes.extend_from_slice(&fnv1a64(&bytes).to_le_bytes());
    crate::film::write_atomically(path, &bytes)
}

fn header_text(h: &PartHeader) -> String {
    let (s, t, c) = (&h.stats, &h.stats.trace, &h.crop);
    format!(
        "{FORMAT}\nrenderer {}\nscene {}\nscene-fnv1a64 {:016x}\nflags {}\ncrop {} {} {} {}\n\
         samples {} {}\nstats {} {} {} {} {} {} {} {} {}\nseconds {}\nend\n",
        h.renderer,
        h.scene.replace('\n', " "),
        h.scene_hash,
        h.flags,
        c.x0,
        c.y0,
        c.x1,
        c.y1,
        h.samples.start,
        h.samples.end,
        s.camera_rays,
        s.bounce_rays,
        s.shadow_rays,
        s.probe_rays,
        s.lane_vertices,
        t.rays,
        t.node_tests,
        t.triangle_tests,
        t.sphere_tests,
        h.seconds
    )
}

/// Reads and checks a part file: a one-line error names the file and what is wrong.
pub fn read_part(path: &Path) -> Result<PartFile> {
    let ctx = |e: Error| e.context(path.display());
    let bytes = std::fs::read(path)
        .map_err(|e| Error::new(format!("{}: cannot read: {e}", path.display())))?;
    if !bytes.starts_with(FORMAT.as_bytes()) {
        bail!("{}: not a pathtracer part file (expected it to begin '{FORMAT}')", path.display());
    }
    let end = find(&bytes, b"\nend\n").ok_or_else(|| {
        Error::new(format!("{}: part file header has no 'end' line", path.display()))
    })? + 5;
    let text = std::str::from_utf8(&bytes[..end])
        .map_err(|_| Error::new(format!("{}: part file header is not text", path.display())))?;
    let header = parse_header(text).map_err(ctx)?;
    let n = header.crop.pixel_count();
    let want = n.checked_mul(PIXEL_BYTES).and_then(|b| b.checked_add(end + 8));
    if want != Some(bytes.len()) {
        bail!(
            "{}: truncated or damaged part file ({} bytes, not the size of crop {})",
            path.display(),
            bytes.len(),
            header.crop
        );
    }
    let (body, sum) = bytes.split_at(bytes.len() - 8);
    if fnv1a64(body).to_le_bytes() != sum {
        bail!("{}: damaged part file (checksum mismatch)", path.display());
    }
    let (counts, sums) = body[end..].chunks_exact(PIXEL_BYTES).map(parse_pixel).unzip();
    Ok(PartFile { header, counts, sums })
}

fn find(haystack: &[u8], needle: &[u8]) -> Option<usize> {
    haystack.windows(needle.len()).position(|w| w == needle)
}

fn parse_pixel(b: &[u8]) -> (u32, ExactRgb) {
    let word = |i: usize, n: usize| &b[i..i + n];
    let count = u32::from_le_bytes(word(0, 4).try_into().unwrap());
    let fixed =
        std::array::from_fn(|c| i128::from_le_bytes(word(4 + 16 * c, 16).try_into().unwrap()));
    let special =
        std::array::from_fn(|c| f32::from_le_bytes(word(52 + 4 * c, 4).try_into().unwrap()));
    (count, ExactRgb { fixed, special })
}

fn parse_header(text: &str) -> Result<PartHeader> {
    let mut lines = text.lines().skip(1);
    let mut field = |key: &str| next_field(&mut lines, key);
    let renderer = field("renderer")?.to_string();
    let scene = field("scene")?.to_string();
    let hash = field("scene-fnv1a64")?;
    let scene_hash = u64::from_str_radix(hash, 16)
        .map_err(|_| Error::new(format!("part file header: bad scene hash '{hash}'")))?;
    let flags = field("flags")?.to_string();
    let c: [u32; 4] = numbers("crop", field("crop")?)?;
    let s: [u32; 2] = numbers("samples", field("samples")?)?;
    let st: [u64; 9] = numbers("stats", field("stats")?)?;
    let secs: [f64; 1] = numbers("seconds", field("seconds")?)?;
    let crop = Rect { x0: c[0], y0: c[1], x1: c[2], y1: c[3] };
    if crop.x0 >= crop.x1 || crop.y0 >= crop.y1 || s[0] >= s[1] {
        bail!("part file header: empty crop {crop} or samples {}..{}", s[0], s[1]);
    }
    let trace =
        TraceStats { rays: st[5], node_tests: st[6], triangle_tests: st[7], sphere_tests: st[8] };
    let stats = RenderStats {
        camera_rays: st[0],
        bounce_rays: st[1],
        shadow_rays: st[2],
        probe_rays: st[3],
        lane_vertices: st[4],
        trace,
    };
    Ok(PartHeader {
        renderer,
        scene,
        scene_hash,
        flags,
        crop,
        samples: s[0]..s[1],
        stats,
        seconds: secs[0],
    })
}

/// The next line's value if it starts with `key` and a space.
fn next_field<'a>(lines: &mut impl Iterator<Item = &'a str>, key: &str) -> Result<&'a str> {
    let line = lines.next().unwrap_or("");
    line.strip_prefix(key)
        .and_then(|rest| rest.strip_prefix(' '))
        .ok_or_else(|| Error::new(format!("part file header: expected '{key} ...', got '{line}'")))
}

fn numbers<T: std::str::FromStr + Copy + Default, const N: usize>(
    key: &str,
    text: &str,
) -> Result<[T; N]> {
    let bad = || Error::new(format!("part file header: bad '{key}' line '{text}'"));
    let words: Vec<&str> = text.split(' ').collect();
    if words.len() != N {
        return Err(bad());
    }
    let mut out = [T::default(); N];
    for (o, w) in out.iter_mut().zip(words) {
        *o = w.parse().map_err(|_| bad())?;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn part() -> PartFile {
        let mut sum = ExactRgb::default();
        sum.add([0.25, -3.0, f32::INFINITY]);
        PartFile {
            header: PartHeader {
                renderer: "0.1.0".into(),
                scene: "a b.dae".into(),
                scene_hash: 0xdead_beef,
                flags: "-r 2 1 -s 4".into(),
                crop: Rect { x0: 0, y0: 0, x1: 2, y1: 1 },
                samples: 1..3,
                stats: RenderStats { camera_rays: 7, ..RenderStats::default() },
                seconds: 0.5,
            },
            counts: vec![2, 0],
            sums: vec![sum, ExactRgb::default()],
        }
    }

    #[test]
    fn parts_round_trip_and_damage_is_refused() {
        let dir = std::env::temp_dir().join(format!("pt-part-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("a.ptpart");
        write_part(&path, &part()).unwrap();
        assert_eq!(read_part(&path).unwrap(), part());
        let good = std::fs::read(&path).unwrap();
        let mut flipped = good.clone();
        let i = good.len() - 20;
        flipped[i] ^= 1;
        for (bytes, want) in [
            (flipped, "checksum"),
            (good[..good.len() - 1].to_vec(), "truncated"),
            (b"P6 hello".to_vec(), "not a pathtracer part"),
            (good[..40].to_vec(), "no 'end' line"),
        ] {
            std::fs::write(&path, bytes).unwrap();
            let err = read_part(&path).unwrap_err().to_string();
            assert!(err.contains(want) && err.contains("a.ptpart"), "{err}");
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
