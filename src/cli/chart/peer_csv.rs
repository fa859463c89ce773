//! Another ray tracer's kernel figures for `pathtracer chart scaling --peer PEERS.csv`: the CSV
//! that the peer harness (`../shared/tools/peer-bench`, `--csv FILE`) writes, one row per peer
//! variant and run. Each row names the scene's `triangles`, the `peer` (e.g. `embree 3.13.5`),
//! its `variant` (`MEDIUM rtcIntersect16/rtcOccluded16`), Mrays/s per ray set and thread count
//! (`primary_1t`, ..., `shadow_2t`) and the build's CPU time at one thread (`build_ms_1t_cpu`).
//! Other columns are ignored. The chart takes, per peer, size, ray set and thread count, the
//! best figure of any variant and run ("its best variant"), and the least build time of its
//! `MEDIUM` variants (all variants when none is called so).

use std::collections::BTreeMap;

/// What the chart draws of one peer at one scene size.
#[derive(Debug, Default, Clone, PartialEq)]
pub struct PeerPoint {
    /// Best Mrays/s over variants and runs, per (ray set, threads).
    pub mrays: BTreeMap<(String, usize), f64>,
    /// Least one-thread build time (ms) of the MEDIUM variants, if any row had one.
    pub build_ms: Option<f64>,
}

/// Per peer name (its first word, `embree`), per triangle count.
pub type PeerTable = BTreeMap<String, BTreeMap<u64, PeerPoint>>;

/// The ray sets and thread counts whose columns are read.
const SETS: [&str; 3] = ["primary", "diffuse", "shadow"];
const THREADS: [usize; 2] = [1, 2];

/// Reads the CSV files and merges their rows; errors name the file (and line).
pub fn read(paths: &[String]) -> Result<PeerTable, String> {
    let mut table = PeerTable::new();
    // Least build time per (peer, size): of the MEDIUM variants, and of any variant.
    let mut builds: BTreeMap<(String, u64), (Option<f64>, f64)> = BTreeMap::new();
    for path in paths {
        let text = std::fs::read_to_string(path).map_err(|e| format!("{path}: {e}"))?;
        let mut lines = text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty());
        let (_, header) = lines.next().ok_or_else(|| format!("{path}: empty (no header)"))?;
        let header = split_row(header).map_err(|e| format!("{path}:1: {e}"))?;
        let col = |name: &str| {
            header.iter().position(|h| h == name).ok_or_else(|| format!("{path}: no column {name}"))
        };
        let (tri_col, peer_col, variant_col) = (col("triangles")?, col("peer")?, col("variant")?);
        let build_col = col("build_ms_1t_cpu")?;
        let rate_cols: Vec<(String, usize, usize)> = SETS
            .iter()
            .flat_map(|s| THREADS.iter().map(move |&t| (s, t)))
            .map(|(s, t)| col(&format!("{s}_{t}t")).map(|c| (s.to_string(), t, c)))
            .collect::<Result<_, _>>()?;
        for (i, line) in lines {
            let at = format!("{path}:{}", i + 1);
            let row = split_row(line).map_err(|e| format!("{at}: {e}"))?;
            if row.len() != header.len() {
                return Err(format!("{at}: {} fields, header has {}", row.len(), header.len()));
            }
            let number = |c: usize| -> Result<f64, String> {
                let v: f64 = row[c]
                    .trim()
                    .parse()
                    .map_err(|_| format!("{at}: {}: not a number", header[c]))?;
                if v.is_finite() && v >= 0.0 {
                    Ok(v)
                } else {
                    Err(format!("{at}: {}: {v} is not a finite figure >= 0", header[c]))
                }
            };
            let triangles = number(tri_col)? as u64;
            let peer = row[peer_col].split_whitespace().next().unwrap_or("peer").to_lowercase();
            let medium = row[variant_col].starts_with("MEDIUM");
            let point = table.entry(peer.clone()).or_default().entry(triangles).or_default();
            for (set, threads, c) in &rate_cols {
                let best = point.mrays.entry((set.clone(), *threads)).or_insert(0.0);
                *best = best.max(number(*c)?);
            }
            let build = number(build_col)?;
            let (medium_ms, any_ms) = builds.entry((peer, triangles)).or_insert((None, f64::MAX));
            *any_ms = any_ms.min(build);
            if medium {
                *medium_ms = Some(medium_ms.map_or(build, |b| b.min(build)));
            }
        }
    }
    for ((peer, triangles), (medium_ms, any_ms)) in builds {
        table.get_mut(&peer).and_then(|p| p.get_mut(&triangles)).expect("row seen").build_ms =
            Some(medium_ms.unwrap_or(any_ms));
    }
    if table.is_empty() {
        return Err(format!("{}: no peer rows", paths.join(", ")));
    }
    Ok(table)
}

/// The fields of one CSV row (RFC 4180: fields in double quotes may hold commas and `""`).
fn split_row(line: &str) -> Result<Vec<String>, String> {
    let mut fields = Vec::new();
    let mut field = String::new();
    let mut chars = line.chars().peekable();
    let mut quoted = false;
    while let Some(c) = chars.next() {
        match (quoted, c) {
            (false, ',') => fields.push(std::mem::take(&mut field)),
            (false, '"') if field.is_empty() => quoted = true,
            (true, '"') if chars.peek() == Some(&'"') => {
                chars.next();
                field.push('"');
            }
            (true, '"') => quoted = false,
            (_, c) => field.push(c),
        }
    }
    if quoted {
        return Err("unterminated quoted field".into());
    }
    fields.push(field);
    Ok(fields)
}

#[cfg(test)]
mod tests {
    use super::*;

    const HEADER: &str = "scene,triangles,peer,variant,build_ms_1t_cpu,primary_1t,primary_2t,\
diffuse_1t,diffuse_2t,shadow_1t,shadow_2t,notes";

    fn write(name: &str, rows: &[&str]) -> String {
        let path = std::env::temp_dir().join(format!("pt-peer-csv-{name}-{}", std::process::id()));
        std::fs::write(&path, format!("{HEADER}\n{}\n", rows.join("\n"))).unwrap();
        path.to_str().unwrap().to_string()
    }

    #[test]
    fn best_variant_per_set_and_medium_build_time() {
        let path = write(
            "ok",
            &[
                r##"t,1000,"embree 3.13.5","HIGH rtcIntersect1/rtcOccluded1",2.0,10,20,3,6,5,10,"a, ""b""""##,
                r#"t,1000,"embree 3.13.5","MEDIUM rtcIntersect16/rtcOccluded16",4.0,30,55,2,4,8,15,x"#,
                r#"t,1000,"embree 3.13.5","MEDIUM rtcIntersect1/rtcOccluded1",3.5,12,24,4,7,6,11,x"#,
                r#"t,5000,"tinybvh 1.6","wide",9.0,1,2,1,2,1,2,x"#,
            ],
        );
        let t = read(std::slice::from_ref(&path)).unwrap();
        let p = &t["embree"][&1000];
        assert_eq!(p.mrays[&("primary".into(), 1)], 30.0);
        assert_eq!(p.mrays[&("diffuse".into(), 2)], 7.0);
        assert_eq!(p.mrays[&("shadow".into(), 2)], 15.0);
        // The HIGH row's 2.0 ms is not Embree MEDIUM's build time.
        assert_eq!(p.build_ms, Some(3.5));
        assert_eq!(t["tinybvh"][&5000].build_ms, Some(9.0));
        let _ = std::fs::remove_file(path);
    }

    #[test]
    fn bad_files_are_one_line_errors() {
        let bad = write("bad", &["t,1000,embree,MEDIUM,1,x,1,1,1,1,1,n"]);
        let e = read(std::slice::from_ref(&bad)).unwrap_err();
        assert!(e.ends_with(":2: primary_1t: not a number"), "{e}");
        let short = write("short", &["t,1000,embree"]);
        assert!(read(std::slice::from_ref(&short))
            .unwrap_err()
            .contains("3 fields, header has 12"));
        let open = write("open", &[r#"t,1000,"embree,MEDIUM,1,1,1,1,1,1,1,n"#]);
        assert!(read(std::slice::from_ref(&open))
            .unwrap_err()
            .contains("unterminated quoted field"));
        for p in [bad, short, open] {
            let _ = std::fs::remove_file(p);
        }
        assert!(read(&["/nonexistent/peers.csv".into()]).unwrap_err().starts_with("/nonexistent"));
    }
}
