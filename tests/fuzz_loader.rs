//! Mutation fuzzing of the COLLADA loader over the course files: byte flips, truncation,
//! deleted and duplicated elements, numbers replaced by NaN/inf/huge/negative values or words,
//! broken and cyclic `url`/`source`/`target` references. Every input must give a scene or a
//! one-line, non-empty `Error`; a panic is a bug. Every scene it gives is then rendered, tiny
//! (`render_tiny`): building its tree and rendering must not panic either (a scene whose
//! coordinates overflowed the tree's box areas once did).
//!
//! The quick campaign runs in CI. The long one is ignored; run it with a count:
//! `PT_FUZZ_COUNT=1000000 cargo test --release --test fuzz_loader -- --ignored --nocapture`.

mod common;

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Instant;

use pathtracer::accel::{Accel, AccelKind};
use pathtracer::sampler::Pcg32;
use pathtracer::scene::{collada, Scene};
use pathtracer::{render, RenderConfig};

/// The course files the campaign mutates: the small ones, so each input parses in microseconds
/// (the big meshes add nothing a mutation of a small mesh does not reach).
const SEED_FILES: &[&str] = &[
    "basic/floating.dae",
    "basic/sphere_diffuse.dae",
    "basic/sphere_glass.dae",
    "basic/sphere_mirror.dae",
    "basic/trigs10.dae",
    "simple/cube.dae",
    "simple/plane.dae",
    "sky/CBempty.dae",
    "sky/CBgems.dae",
    "sky/CBspheres.dae",
    "sky/CBspheres_lambertian.dae",
    "sky/CBspheres_microfacet_al_ag.dae",
];

/// Numbers the loader must refuse or survive.
const BAD_NUMBERS: &[&str] = &[
    "NaN",
    "nan",
    "inf",
    "-inf",
    "infinity",
    "1e39",
    "-1e39",
    "3.4e38",
    "-3.4e38",
    "1e-45",
    "-1",
    "-0",
    "0",
    "1",
    "2",
    "3",
    "4294967295",
    "4294967296",
    "18446744073709551615",
    "18446744073709551616",
    "99999999999999999999999",
    "1e308",
    "abc",
    "",
    "1.5.5",
    "0x10",
    "--1",
    "+",
    "e5",
    "2147483648",
];

const REF_ATTRS: &[&str] = &["url=\"", "source=\"", "target=\"", "symbol=\"", "material=\""];

/// One mutation of `text`, chosen and placed by `rng`.
fn mutate(text: &str, rng: &mut Pcg32) -> String {
    let below = |rng: &mut Pcg32, n: usize| (rng.next_u32() as usize) % n.max(1);
    match below(rng, 8) {
        // Byte flips: arbitrary bytes, so the result may not be UTF-8 (read as `load` would
        // fail on it; the lossy text still exercises the XML parser).
        0 if text.is_empty() => String::new(),
        0 => {
            let mut bytes = text.as_bytes().to_vec();
            for _ in 0..1 + below(rng, 4) {
                let i = below(rng, bytes.len());
                bytes[i] ^= 1 << below(rng, 8);
            }
            String::from_utf8_lossy(&bytes).into_owned()
        }
        // Truncation at a character boundary.
        1 => {
            let mut i = below(rng, text.len());
            while !text.is_char_boundary(i) {
                i -= 1;
            }
            text[..i].to_string()
        }
        // Delete or duplicate an element.
        2 | 3 => match element_span(text, rng) {
            Some((s, e)) if below(rng, 2) == 0 => format!("{}{}", &text[..s], &text[e..]),
            Some((s, e)) => format!("{}{}{}", &text[..e], &text[s..e], &text[e..]),
            None => text.to_string(),
        },
        // Replace a number (in text or attributes) with a bad one.
        4 | 5 => {
            let spans = number_spans(text);
            if spans.is_empty() {
                return text.to_string();
            }
            let (s, e) = spans[below(rng, spans.len())];
            let bad = BAD_NUMBERS[below(rng, BAD_NUMBERS.len())];
            format!("{}{bad}{}", &text[..s], &text[e..])
        }
        // Break a reference: dangling, empty, or pointing at another element (of the wrong
        // kind, or an enclosing node: a cycle).
        6 => {
            let attr = REF_ATTRS[below(rng, REF_ATTRS.len())];
            let starts: Vec<usize> =
                text.match_indices(attr).map(|(i, _)| i + attr.len()).collect();
            if starts.is_empty() {
                return text.to_string();
            }
            let s = starts[below(rng, starts.len())];
            let e = s + text[s..].find('"').unwrap_or(0);
            let ids = ids(text);
            let value = match below(rng, 4) {
                0 => "#no-such-id".to_string(),
                1 => String::new(),
                2 => "#".to_string(),
                _ if ids.is_empty() => "#x".into(),
                _ => format!("#{}", ids[below(rng, ids.len())]),
            };
            format!("{}{value}{}", &text[..s], &text[e..])
        }
        // Insert an instance_node naming a random id (often an ancestor: infinite recursion
        // unless the loader bounds it).
        _ => {
            let nodes: Vec<usize> = text.match_indices("<node").map(|(i, _)| i).collect();
            let ids = ids(text);
            if nodes.is_empty() || ids.is_empty() {
                return text.to_string();
            }
            let at = nodes[below(rng, nodes.len())];
            let Some(close) = text[at..].find('>') else { return text.to_string() };
            let at = at + close + 1;
            let id = ids[below(rng, ids.len())];
            format!("{}<instance_node url=\"#{id}\"/>{}", &text[..at], &text[at..])
        }
    }
}

/// The byte range of a random element `<name ...>...</name>` or `<name .../>`.
fn element_span(text: &str, rng: &mut Pcg32) -> Option<(usize, usize)> {
    let opens: Vec<usize> = text
        .match_indices('<')
        .map(|(i, _)| i)
        .filter(|&i| text[i + 1..].starts_with(|c: char| c.is_ascii_alphabetic()))
        .collect();
    if opens.is_empty() {
        return None;
    }
    let s = opens[(rng.next_u32() as usize) % opens.len()];
    let name_end = s + 1 + text[s + 1..].find([' ', '\n', '\t', '>', '/'])?;
    let name = &text[s + 1..name_end];
    let tag_end = s + text[s..].find('>')? + 1;
    if text[..tag_end].ends_with("/>") {
        return Some((s, tag_end));
    }
    let close = format!("</{name}>");
    let e = tag_end + text[tag_end..].find(&close)? + close.len();
    Some((s, e))
}

/// Byte ranges of number-like tokens.
fn number_spans(text: &str) -> Vec<(usize, usize)> {
    let b = text.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        if b[i].is_ascii_digit() || (b[i] == b'-' && i + 1 < b.len() && b[i + 1].is_ascii_digit()) {
            let s = i;
            i += 1;
            while i < b.len()
                && (b[i].is_ascii_digit() || matches!(b[i], b'.' | b'e' | b'E' | b'-' | b'+'))
            {
                i += 1;
            }
            out.push((s, i));
        } else {
            i += 1;
        }
    }
    out
}

fn ids(text: &str) -> Vec<&str> {
    text.match_indices("id=\"")
        .filter_map(|(i, m)| {
            let s = i + m.len();
            text[s..].find('"').map(|e| &text[s..s + e])
        })
        .collect()
}

#[derive(Default)]
struct Tally {
    inputs: AtomicUsize,
    scenes: AtomicUsize,
    errors: AtomicUsize,
    panics: AtomicUsize,
    bad_messages: AtomicUsize,
    /// Scenes whose tiny render has a NaN or infinite pixel: reported, not a failure (finite
    /// but absurd values, such as an albedo of 3.4e38, overflow f32 on the way).
    non_finite: AtomicUsize,
    /// The first few failing inputs, to report and to turn into regression tests.
    failures: Mutex<Vec<(String, String)>>,
}

/// Runs `count` mutated inputs (1 to 3 stacked mutations each) split over `threads` threads.
fn campaign(count: usize, threads: usize, seed: u64) -> Option<Tally> {
    let dir = common::scenes_dir()?;
    let seeds: Vec<(PathBuf, String)> = SEED_FILES
        .iter()
        .map(|f| {
            let p = dir.join(f);
            let t = std::fs::read_to_string(&p).unwrap();
            (p, t)
        })
        .collect();
    let tally = Tally::default();
    // Panics in the loader or a tiny render are counted, not printed: a million backtraces
    // would drown the report. Any other panic (in the harness itself) still prints.
    let hook = std::sync::Arc::new(std::panic::take_hook());
    let print = hook.clone();
    std::panic::set_hook(Box::new(move |info| {
        if !IN_CHECKED_CODE.with(|f| f.get()) {
            print(info)
        }
    }));
    std::thread::scope(|s| {
        for t in 0..threads {
            let (seeds, tally) = (&seeds, &tally);
            s.spawn(move || {
                let mut rng = Pcg32::new(seed, t as u64);
                for _ in (t..count).step_by(threads) {
                    let (_, original) = &seeds[(rng.next_u32() as usize) % seeds.len()];
                    let mut text = mutate(original, &mut rng);
                    for _ in 0..rng.next_u32() % 3 {
                        text = mutate(&text, &mut rng);
                    }
                    check(&text, tally);
                }
            });
        }
    });
    let _ = std::panic::take_hook();
    if let Ok(hook) = std::sync::Arc::try_unwrap(hook) {
        std::panic::set_hook(hook);
    }
    Some(tally)
}

thread_local! {
    static IN_CHECKED_CODE: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

fn check(text: &str, tally: &Tally) {
    tally.inputs.fetch_add(1, Ordering::Relaxed);
    let fail = |why: String| {
        let mut f = tally.failures.lock().unwrap();
        if f.len() < 5 {
            f.push((why, text.to_string()));
        }
    };
    IN_CHECKED_CODE.with(|f| f.set(true));
    let result = catch_unwind(AssertUnwindSafe(|| collada::parse(text)));
    IN_CHECKED_CODE.with(|f| f.set(false));
    match result {
        Ok(Ok(scene)) => {
            tally.scenes.fetch_add(1, Ordering::Relaxed);
            if let Err(e) = scene.validate() {
                tally.bad_messages.fetch_add(1, Ordering::Relaxed);
                fail(format!("loader returned an invalid scene: {e}"));
            } else if !scene.lights.iter().all(collada::light_is_finite) {
                tally.bad_messages.fetch_add(1, Ordering::Relaxed);
                fail("loader returned a light that is not finite".into());
            } else {
                IN_CHECKED_CODE.with(|f| f.set(true));
                let rendered = catch_unwind(AssertUnwindSafe(|| render_tiny(&scene)));
                IN_CHECKED_CODE.with(|f| f.set(false));
                match rendered {
                    Ok(Ok(finite)) => {
                        if !finite {
                            tally.non_finite.fetch_add(1, Ordering::Relaxed);
                        }
                    }
                    Ok(Err(m)) => {
                        tally.bad_messages.fetch_add(1, Ordering::Relaxed);
                        fail(format!("bad render error message: {m:?}"));
                    }
                    Err(payload) => {
                        tally.panics.fetch_add(1, Ordering::Relaxed);
                        fail(format!("render panic: {}", panic_message(payload.as_ref())));
                    }
                }
            }
        }
        Ok(Err(e)) => {
            tally.errors.fetch_add(1, Ordering::Relaxed);
            let m = e.to_string();
            if m.trim().is_empty() || m.contains('\n') || m.contains('\r') {
                tally.bad_messages.fetch_add(1, Ordering::Relaxed);
                fail(format!("bad error message: {m:?}"));
            }
        }
        Err(payload) => {
            tally.panics.fetch_add(1, Ordering::Relaxed);
            fail(format!("panic: {}", panic_message(payload.as_ref())));
        }
    }
}

fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_default()
}

/// Builds `scene`'s tree and renders it at 8 x 6 pixels, 2 samples, depths 1 and 4, with each
/// estimator. Ok(whether every pixel is finite), or the first error that is not one
/// non-empty line. An error is a fine answer (a render refusing the scene); a panic is not.
fn render_tiny(scene: &Scene) -> Result<bool, String> {
    let accel = match Accel::try_build(scene, AccelKind::Bvh) {
        Ok(accel) => accel,
        Err(e) => return one_line(e.to_string()).map(|_| true),
    };
    let mut finite = true;
    for integrator in [common::LIGHT, common::MIS, common::HEMISPHERE] {
        for max_depth in [1, 4] {
            let config = RenderConfig {
                integrator,
                width: 8,
                height: 6,
                spp: 2,
                max_depth,
                threads: 1,
                seed: 3,
                ..RenderConfig::default()
            };
            match render(scene, &accel, &config) {
                Ok(out) => finite &= out.pixels.iter().all(|p| p.is_finite()),
                Err(e) => one_line(e.to_string())?,
            }
        }
    }
    Ok(finite)
}

fn one_line(m: String) -> Result<(), String> {
    if m.trim().is_empty() || m.contains('\n') || m.contains('\r') {
        Err(m)
    } else {
        Ok(())
    }
}

fn run_and_assert(count: usize, threads: usize, seed: u64) {
    let start = Instant::now();
    let Some(t) = campaign(count, threads, seed) else { return };
    let secs = start.elapsed().as_secs_f64();
    let (n, ok, err) = (
        t.inputs.load(Ordering::Relaxed),
        t.scenes.load(Ordering::Relaxed),
        t.errors.load(Ordering::Relaxed),
    );
    let (panics, bad) = (t.panics.load(Ordering::Relaxed), t.bad_messages.load(Ordering::Relaxed));
    let non_finite = t.non_finite.load(Ordering::Relaxed);
    eprintln!(
        "fuzz: {n} inputs in {secs:.1} s on {threads} threads ({:.0}/s): {ok} scenes (rendered; \
         {non_finite} with a NaN or infinite pixel), {err} errors, {panics} panics, {bad} bad \
         messages",
        n as f64 / secs
    );
    let failures = t.failures.lock().unwrap();
    for (why, text) in failures.iter() {
        let path = std::env::temp_dir().join(format!("pt-fuzz-failure-{}.dae", text.len()));
        let _ = std::fs::write(&path, text);
        eprintln!("  {why} (input saved to {})", path.display());
    }
    assert_eq!(n, count);
    assert!(panics == 0 && bad == 0, "{panics} panics and {bad} bad results; see above");
    // The mutations must reach both outcomes, or the campaign tests nothing.
    assert!(
        ok > count / 20 && err > count / 20,
        "{ok} scenes, {err} errors: mutations too weak or too strong"
    );
}

#[test]
fn mutated_course_files_load_or_fail_cleanly() {
    run_and_assert(4000, 2, 184);
}

#[test]
#[ignore = "long campaign: PT_FUZZ_COUNT=1000000 cargo test --release --test fuzz_loader -- --ignored"]
fn long_fuzz_campaign() {
    let count =
        std::env::var("PT_FUZZ_COUNT").ok().and_then(|v| v.parse().ok()).unwrap_or(1_000_000);
    let seed = std::env::var("PT_FUZZ_SEED").ok().and_then(|v| v.parse().ok()).unwrap_or(1);
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    run_and_assert(count, threads, seed);
}

/// Regression inputs the campaign found; each once panicked or hung the loader.
#[test]
fn fuzz_regressions() {
    let base = |body: &str| {
        format!(
            r##"<COLLADA><library_geometries><geometry id="g"><mesh>
            <source id="p"><float_array id="pa">0 0 0 1 0 0 0 1 0</float_array></source>
            <vertices id="v"><input semantic="POSITION" source="#p"/></vertices>
            {body}</mesh></geometry></library_geometries>
            <library_visual_scenes><visual_scene id="s"><node id="n">
            <instance_geometry url="#g"/></node></visual_scene></library_visual_scenes></COLLADA>"##
        )
    };
    let cases = [
        // An offset of u64::MAX: the stride offset + 1 overflowed to 0 (division by zero).
        base(
            r##"<triangles count="1"><input semantic="VERTEX" source="#v" offset="18446744073709551615"/><p>0 1 2</p></triangles>"##,
        ),
        // A huge offset: n * stride overflowed.
        base(
            r##"<polylist count="1"><input semantic="VERTEX" source="#v" offset="9223372036854775807"/><vcount>3</vcount><p>0 1 2</p></polylist>"##,
        ),
        base(
            r##"<polylist count="1"><input semantic="VERTEX" source="#v" offset="0"/><vcount>4294967295</vcount><p>0 1 2</p></polylist>"##,
        ),
    ];
    for text in cases {
        let r = catch_unwind(|| collada::parse(&text));
        let e = r.expect("loader panicked").expect_err("should be an error").to_string();
        assert!(!e.is_empty() && !e.contains('\n'), "{e}");
    }
    // Finite matrix entries whose product overflows put a light at infinity.
    let huge_light = r##"<COLLADA><library_lights><light id="l"><technique_common><point>
        <color>1 1 1</color></point></technique_common></light></library_lights>
        <library_visual_scenes><visual_scene id="s"><node id="a">
        <matrix>3e38 0 0 3e38 0 1 0 0 0 0 1 0 0 0 0 1</matrix>
        <node id="b"><matrix>1 0 0 3e38 0 1 0 0 0 0 1 0 0 0 0 1</matrix>
        <instance_light url="#l"/></node></node></visual_scene></library_visual_scenes></COLLADA>"##;
    let e = collada::parse(huge_light).expect_err("a light at infinity is an error").to_string();
    assert!(e.contains("not finite"), "{e}");
    // A node that instances itself: unbounded recursion (a stack overflow aborts the process,
    // which catch_unwind cannot catch) unless the loader bounds the depth.
    let cyclic = r##"<COLLADA><library_nodes><node id="a"><instance_node url="#a"/></node></library_nodes>
        <library_visual_scenes><visual_scene id="s"><node id="r"><instance_node url="#a"/></node>
        </visual_scene></library_visual_scenes></COLLADA>"##;
    let e = collada::parse(cyclic).expect_err("a cycle is an error").to_string();
    assert!(e.contains("cycle"), "{e}");
}
