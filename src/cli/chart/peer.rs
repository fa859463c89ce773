//! Another renderer's measurements for `pathtracer chart accuracy --peer FILE.jsonl`.
//!
//! The file is JSON Lines written by an external measuring tool, one flat object per render:
//!
//! ```text
//! {"scene": "CBbunny.dae", "size": "400x300", "m": 5, "spp": 16, "renderer": "ours mis", "seconds": 1.39, "rel_noise": 0.198}
//! ```
//!
//! Required fields: `scene` (a file name, matched against the charted scene's file name),
//! `size`, `renderer` (strings), `m`, `spp` (whole numbers, `spp` > 0), `seconds` and
//! `rel_noise` (numbers > 0; `rel_noise` is one render's relative noise, which for an unbiased
//! renderer compares with relative RMSE against the converged image). Other fields are
//! allowed and ignored, but every value must be a string or a number: objects, arrays, `true`,
//! `false` and `null` are errors, as are duplicate keys. Blank lines are skipped.
//!
//! The parser is [`parse_flat_object`], strict RFC 8259 for that subset, written here so the
//! crate needs no JSON dependency.

use std::collections::BTreeMap;
use std::path::Path;

/// A value of a flat JSON object: the two kinds a peer line holds.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    Str(String),
    Num(f64),
}

/// One peer render, validated.
#[derive(Debug, Clone, PartialEq)]
pub struct Record {
    /// 1-based line in the file.
    pub line: usize,
    pub scene: String,
    pub size: String,
    pub m: u32,
    pub spp: u32,
    pub renderer: String,
    pub seconds: f64,
    pub rel_noise: f64,
}

/// One chart series: the records of one (renderer, size) at one depth, by spp then time.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Legend text, e.g. "mitsuba3 path (quad), peer run 400x300".
    pub label: String,
    pub renderer: String,
    pub size: String,
    pub points: Vec<Record>,
}

/// Reads `path` and returns its records for the scene whose file name is `scene_name`. Every
/// line is checked, whatever its scene; errors are one line naming the file (and line).
pub fn read(path: &Path, scene_name: &str) -> Result<Vec<Record>, String> {
    let name = path.display();
    let text = std::fs::read_to_string(path).map_err(|e| format!("{name}: {e}"))?;
    let mut all = Vec::new();
    for (i, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        all.push(parse_record(line, i + 1).map_err(|e| format!("{name}:{}: {e}", i + 1))?);
    }
    let count = all.len();
    let mut scenes: Vec<String> = all.iter().map(|r| r.scene.clone()).collect();
    let records: Vec<Record> = all.into_iter().filter(|r| r.scene == scene_name).collect();
    if records.is_empty() {
        scenes.sort();
        scenes.dedup();
        let seen = if scenes.is_empty() { "none".into() } else { scenes.join(", ") };
        return Err(format!(
            "{name}: no record for scene '{scene_name}' ({count} records; scenes: {seen})"
        ));
    }
    Ok(records)
}

/// The series of the records at depth `m`, one per (renderer, size) in order of first
/// appearance, points sorted by spp then seconds.
pub fn series(records: &[Record], m: u32) -> Vec<Series> {
    let mut out: Vec<Series> = Vec::new();
    for r in records.iter().filter(|r| r.m == m) {
        match out.iter_mut().find(|s| s.renderer == r.renderer && s.size == r.size) {
            Some(s) => s.points.push(r.clone()),
            None => out.push(Series {
                label: format!("{}, peer run {}", r.renderer, r.size),
                renderer: r.renderer.clone(),
                size: r.size.clone(),
                points: vec![r.clone()],
            }),
        }
    }
    for s in &mut out {
        s.points.sort_by(|a, b| a.spp.cmp(&b.spp).then(a.seconds.total_cmp(&b.seconds)));
    }
    out
}

/// One line into a validated record (`line` is only stored).
pub fn parse_record(text: &str, line: usize) -> Result<Record, String> {
    let obj = parse_flat_object(text)?;
    let string = |key: &str| match obj.get(key) {
        Some(Value::Str(s)) => Ok(s.clone()),
        Some(Value::Num(_)) => Err(format!("field '{key}': expected a string, got a number")),
        None => Err(format!("missing field '{key}'")),
    };
    let number = |key: &str| match obj.get(key) {
        Some(Value::Num(v)) => Ok(*v),
        Some(Value::Str(_)) => Err(format!("field '{key}': expected a number, got a string")),
        None => Err(format!("missing field '{key}'")),
    };
    let whole = |key: &str, lo: u32| {
        let v = number(key)?;
        if v.fract() != 0.0 || v < lo as f64 || v > u32::MAX as f64 {
            return Err(format!("field '{key}': {v} is not a whole number >= {lo}"));
        }
        Ok(v as u32)
    };
    let positive = |key: &str| {
        let v = number(key)?;
        if !(v > 0.0) {
            return Err(format!("field '{key}': {v} is not positive"));
        }
        Ok(v)
    };
    Ok(Record {
        line,
        scene: string("scene")?,
        size: string("size")?,
        m: whole("m", 0)?,
        spp: whole("spp", 1)?,
        renderer: string("renderer")?,
        seconds: positive("seconds")?,
        rel_noise: positive("rel_noise")?,
    })
}

/// Parses one JSON object whose values are all strings or numbers. Strict: the RFC 8259
/// grammar for that subset (escapes, surrogate pairs, number syntax), nothing but whitespace
/// after the object, no duplicate keys, no numbers that overflow to infinity. Errors name the
/// 1-based column (in characters).
pub fn parse_flat_object(text: &str) -> Result<BTreeMap<String, Value>, String> {
    let mut p = Parser { text, pos: 0 };
    p.object()
}

struct Parser<'a> {
    text: &'a str,
    /// Byte offset into `text`.
    pos: usize,
}

impl Parser<'_> {
    fn err(&self, msg: impl std::fmt::Display) -> String {
        format!("column {}: {msg}", self.text[..self.pos].chars().count() + 1)
    }

    fn peek(&self) -> Option<u8> {
        self.text.as_bytes().get(self.pos).copied()
    }

    fn skip_ws(&mut self) {
        while let Some(b' ' | b'\t' | b'\n' | b'\r') = self.peek() {
            self.pos += 1;
        }
    }

    fn expect(&mut self, byte: u8, what: &str) -> Result<(), String> {
        self.skip_ws();
        if self.peek() == Some(byte) {
            self.pos += 1;
            Ok(())
        } else {
            Err(self.err(format!("expected {what}, found {}", self.found())))
        }
    }

    fn found(&self) -> String {
        match self.text[self.pos..].chars().next() {
            None => "end of line".into(),
            Some(c) => format!("'{}'", c.escape_default()),
        }
    }

    fn object(&mut self) -> Result<BTreeMap<String, Value>, String> {
        let mut map = BTreeMap::new();
        self.expect(b'{', "'{'")?;
        self.skip_ws();
        if self.peek() == Some(b'}') {
            self.pos += 1;
        } else {
            loop {
                self.skip_ws();
                let key_pos = self.pos;
                if self.peek() != Some(b'"') {
                    return Err(self.err(format!("expected a key string, found {}", self.found())));
                }
                let key = self.string()?;
                self.expect(b':', "':'")?;
                let value = self.value(&key)?;
                if map.insert(key.clone(), value).is_some() {
                    self.pos = key_pos;
                    return Err(self.err(format!("duplicate key '{key}'")));
                }
                self.skip_ws();
                match self.peek() {
                    Some(b',') => self.pos += 1,
                    Some(b'}') => {
                        self.pos += 1;
                        break;
                    }
                    _ => {
                        return Err(
                            self.err(format!("expected ',' or '}}', found {}", self.found()))
                        )
                    }
                }
            }
        }
        self.skip_ws();
        if self.pos < self.text.len() {
            return Err(self.err(format!("unexpected {} after the object", self.found())));
        }
        Ok(map)
    }

    fn value(&mut self, key: &str) -> Result<Value, String> {
        self.skip_ws();
        match self.peek() {
            Some(b'"') => Ok(Value::Str(self.string()?)),
            Some(b'-' | b'0'..=b'9') => Ok(Value::Num(self.number()?)),
            Some(b'{' | b'[' | b't' | b'f' | b'n') => Err(self.err(format!(
                "value of '{key}': only strings and numbers are supported, found {}",
                self.found()
            ))),
            _ => {
                Err(self.err(format!("value of '{key}': expected a value, found {}", self.found())))
            }
        }
    }

    /// A string starting at the opening quote.
    fn string(&mut self) -> Result<String, String> {
        let bytes = self.text.as_bytes();
        self.pos += 1;
        let mut out = String::new();
        let mut run = self.pos;
        loop {
            match bytes.get(self.pos) {
                None => return Err(self.err("unterminated string")),
                Some(b'"') => {
                    out.push_str(&self.text[run..self.pos]);
                    self.pos += 1;
                    return Ok(out);
                }
                Some(b'\\') => {
                    out.push_str(&self.text[run..self.pos]);
                    self.pos += 1;
                    let simple = match bytes.get(self.pos) {
                        Some(b'"') => Some('"'),
                        Some(b'\\') => Some('\\'),
                        Some(b'/') => Some('/'),
                        Some(b'b') => Some('\u{8}'),
                        Some(b'f') => Some('\u{c}'),
                        Some(b'n') => Some('\n'),
                        Some(b'r') => Some('\r'),
                        Some(b't') => Some('\t'),
                        Some(b'u') => None,
                        _ => return Err(self.err(format!("bad escape \\{}", self.found()))),
                    };
                    self.pos += 1;
                    out.push(match simple {
                        Some(c) => c,
                        None => self.unicode_escape()?,
                    });
                    run = self.pos;
                }
                Some(&b) if b < 0x20 => {
                    return Err(self.err("control character in string (must be escaped)"))
                }
                Some(_) => self.pos += 1,
            }
        }
    }

    /// The four hex digits after `\u` (and a low surrogate's `\uXXXX` after a high one).
    fn unicode_escape(&mut self) -> Result<char, String> {
        let hi = self.hex4()?;
        let code = match hi {
            0xD800..=0xDBFF => {
                if !self.text[self.pos..].starts_with("\\u") {
                    return Err(self.err("high surrogate without a low surrogate"));
                }
                self.pos += 2;
                let lo = self.hex4()?;
                if !(0xDC00..=0xDFFF).contains(&lo) {
                    return Err(self.err("high surrogate without a low surrogate"));
                }
                0x10000 + ((hi - 0xD800) << 10) + (lo - 0xDC00)
            }
            0xDC00..=0xDFFF => return Err(self.err("low surrogate without a high surrogate")),
            c => c,
        };
        // Valid by construction: not a surrogate and at most 0x10FFFF.
        char::from_u32(code).ok_or_else(|| self.err("invalid \\u escape"))
    }

    fn hex4(&mut self) -> Result<u32, String> {
        let digits = self.text.get(self.pos..self.pos + 4).unwrap_or("");
        if digits.len() != 4 || !digits.bytes().all(|b| b.is_ascii_hexdigit()) {
            return Err(self.err("\\u needs four hex digits"));
        }
        self.pos += 4;
        Ok(u32::from_str_radix(digits, 16).expect("checked hex digits"))
    }

    /// `-? (0 | [1-9][0-9]*) (. [0-9]+)? ([eE] [+-]? [0-9]+)?`, finite.
    fn number(&mut self) -> Result<f64, String> {
        let bytes = self.text.as_bytes();
        let start = self.pos;
        let digits = |p: &mut Self| {
            let from = p.pos;
            while let Some(b'0'..=b'9') = bytes.get(p.pos) {
                p.pos += 1;
            }
            p.pos - from
        };
        if bytes.get(self.pos) == Some(&b'-') {
            self.pos += 1;
        }
        match bytes.get(self.pos) {
            Some(b'0') => {
                self.pos += 1;
                if let Some(b'0'..=b'9') = bytes.get(self.pos) {
                    return Err(self.err("leading zero in a number"));
                }
            }
            Some(b'1'..=b'9') => {
                digits(self);
            }
            _ => return Err(self.err(format!("expected a digit, found {}", self.found()))),
        }
        if bytes.get(self.pos) == Some(&b'.') {
            self.pos += 1;
            if digits(self) == 0 {
                return Err(self.err("expected a digit after '.'"));
            }
        }
        if let Some(b'e' | b'E') = bytes.get(self.pos) {
            self.pos += 1;
            if let Some(b'+' | b'-') = bytes.get(self.pos) {
                self.pos += 1;
            }
            if digits(self) == 0 {
                return Err(self.err("expected a digit in the exponent"));
            }
        }
        let text = &self.text[start..self.pos];
        match text.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => {
                self.pos = start;
                Err(self.err(format!("number {text} is out of range")))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const LINE: &str = r#"{"scene": "CBbunny.dae", "size": "400x300", "m": 5, "spp": 16, "renderer": "mitsuba3 path (arealight)", "mitsuba_mapping": "arealight", "seconds": 2.4095, "rel_noise": 0.12671, "noise_sqrt_seconds": 0.19669, "threads": 2}"#;

    fn s(v: &str) -> Value {
        Value::Str(v.into())
    }

    #[test]
    fn parses_the_tools_lines() {
        let obj = parse_flat_object(LINE).unwrap();
        assert_eq!(obj.len(), 10);
        assert_eq!(obj["renderer"], s("mitsuba3 path (arealight)"));
        assert_eq!(obj["seconds"], Value::Num(2.4095));
        assert_eq!(obj["threads"], Value::Num(2.0));
        let r = parse_record(LINE, 7).unwrap();
        assert_eq!(
            r,
            Record {
                line: 7,
                scene: "CBbunny.dae".into(),
                size: "400x300".into(),
                m: 5,
                spp: 16,
                renderer: "mitsuba3 path (arealight)".into(),
                seconds: 2.4095,
                rel_noise: 0.12671,
            }
        );
    }

    #[test]
    fn objects_whitespace_and_empty() {
        assert!(parse_flat_object("{}").unwrap().is_empty());
        assert!(parse_flat_object(" \t{ }\r ").unwrap().is_empty());
        let obj = parse_flat_object("{\"a\":1,\"b\" : \"x\" }").unwrap();
        assert_eq!((obj["a"].clone(), obj["b"].clone()), (Value::Num(1.0), s("x")));
    }

    #[test]
    fn numbers_follow_the_json_grammar() {
        for (text, want) in [
            ("0", 0.0),
            ("-0", 0.0),
            ("7", 7.0),
            ("-12.5", -12.5),
            ("1e3", 1000.0),
            ("2.5E-2", 0.025),
            ("1e+2", 100.0),
            ("0.001", 0.001),
        ] {
            let obj = parse_flat_object(&format!("{{\"x\":{text}}}")).unwrap();
            assert_eq!(obj["x"], Value::Num(want), "{text}");
        }
        for text in
            ["01", "+1", ".5", "1.", "1e", "1e+", "-", "--1", "0x10", "1.5.2", "NaN", "Infinity"]
        {
            let line = format!("{{\"x\":{text}}}");
            assert!(parse_flat_object(&line).is_err(), "accepted {line}");
        }
        let e = parse_flat_object("{\"x\":1e999}").unwrap_err();
        assert!(e.contains("out of range"), "{e}");
    }

    #[test]
    fn strings_decode_escapes_and_unicode() {
        let obj = parse_flat_object(
            r#"{"a":"q\"b\\s\/n\nt\tr\rb\bf\f","u":"\u00e9\u20AC","p":"\ud83d\ude00","raw":"é€😀"}"#,
        )
        .unwrap();
        assert_eq!(obj["a"], s("q\"b\\s/n\nt\tr\rb\u{8}f\u{c}"));
        assert_eq!(obj["u"], s("é€"));
        assert_eq!(obj["p"], s("😀"));
        assert_eq!(obj["raw"], s("é€😀"));
        for (line, want) in [
            (r#"{"a":"x\q"}"#, "bad escape"),
            (r#"{"a":"\u12"}"#, "four hex digits"),
            (r#"{"a":"\u12G4"}"#, "four hex digits"),
            (r#"{"a":"\ud83d"}"#, "low surrogate"),
            (r#"{"a":"\ud83d\u0041"}"#, "low surrogate"),
            (r#"{"a":"\ude00"}"#, "high surrogate"),
            ("{\"a\":\"tab\there\"}", "control character"),
            (r#"{"a":"open}"#, "unterminated"),
        ] {
            let e = parse_flat_object(line).unwrap_err();
            assert!(e.contains(want), "{line}: {e}");
        }
    }

    #[test]
    fn rejects_malformed_and_unsupported_objects() {
        for (line, want) in [
            ("", "expected '{'"),
            ("[1]", "expected '{'"),
            ("{", "expected a key"),
            ("{\"a\":1", "expected ',' or '}'"),
            ("{\"a\":1,}", "expected a key"),
            ("{\"a\" 1}", "expected ':'"),
            ("{a:1}", "expected a key"),
            ("{'a':1}", "expected a key"),
            ("{\"a\":}", "expected a value"),
            ("{\"a\":1 \"b\":2}", "expected ',' or '}'"),
            ("{\"a\":1}{}", "after the object"),
            ("{\"a\":1} x", "after the object"),
            ("{\"a\":null}", "only strings and numbers"),
            ("{\"a\":true}", "only strings and numbers"),
            ("{\"a\":[1]}", "only strings and numbers"),
            ("{\"a\":{\"b\":1}}", "only strings and numbers"),
            ("{\"a\":1,\"a\":2}", "duplicate key 'a'"),
        ] {
            let e = parse_flat_object(line).unwrap_err();
            assert!(e.contains(want), "{line:?}: want '{want}', got '{e}'");
            assert!(e.starts_with("column "), "{e}");
        }
        assert_eq!(
            parse_flat_object("{\"a\":1,,}").unwrap_err(),
            "column 8: expected a key string, found ','"
        );
    }

    #[test]
    fn records_need_every_field_with_its_type_and_range() {
        let without = |key: &str| {
            let obj = parse_flat_object(LINE).unwrap();
            let fields: Vec<String> = obj
                .iter()
                .filter(|(k, _)| *k != key)
                .map(|(k, v)| match v {
                    Value::Str(t) => format!("\"{k}\":\"{t}\""),
                    Value::Num(n) => format!("\"{k}\":{n}"),
                })
                .collect();
            format!("{{{}}}", fields.join(","))
        };
        for key in ["scene", "size", "m", "spp", "renderer", "seconds", "rel_noise"] {
            let e = parse_record(&without(key), 1).unwrap_err();
            assert_eq!(e, format!("missing field '{key}'"));
        }
        assert!(parse_record(&without("threads"), 1).is_ok(), "extra fields are optional");
        for (from, to, want) in [
            ("\"m\": 5", "\"m\": \"5\"", "expected a number"),
            ("\"size\": \"400x300\"", "\"size\": 400", "expected a string"),
            ("\"m\": 5", "\"m\": 2.5", "not a whole number"),
            ("\"m\": 5", "\"m\": -1", "not a whole number"),
            ("\"spp\": 16", "\"spp\": 0", "not a whole number >= 1"),
            ("\"seconds\": 2.4095", "\"seconds\": 0", "not positive"),
            ("\"rel_noise\": 0.12671", "\"rel_noise\": -0.1", "not positive"),
        ] {
            let line = LINE.replace(from, to);
            assert_ne!(line, LINE);
            let e = parse_record(&line, 1).unwrap_err();
            assert!(e.contains(want), "{to}: {e}");
        }
    }

    fn temp_file(name: &str, text: &str) -> std::path::PathBuf {
        let p = std::env::temp_dir().join(format!("pt-peer-{}-{name}", std::process::id()));
        std::fs::write(&p, text).unwrap();
        p
    }

    #[test]
    fn read_filters_by_scene_and_names_file_and_line() {
        let other = LINE.replace("CBbunny.dae", "CBspheres.dae");
        let quad = LINE.replace("(arealight)", "(quad)").replace("\"spp\": 16", "\"spp\": 4");
        let m1 = LINE.replace("\"m\": 5", "\"m\": 1");
        let p = temp_file("ok.jsonl", &format!("{LINE}\n\n{other}\n{quad}\r\n{m1}\n{LINE}\n"));
        let records = read(&p, "CBbunny.dae").unwrap();
        assert_eq!(records.iter().map(|r| r.line).collect::<Vec<_>>(), [1, 4, 5, 6]);
        let at5 = series(&records, 5);
        let labels: Vec<&str> = at5.iter().map(|s| s.label.as_str()).collect();
        assert_eq!(
            labels,
            [
                "mitsuba3 path (arealight), peer run 400x300",
                "mitsuba3 path (quad), peer run 400x300"
            ]
        );
        assert_eq!(at5[0].points.len(), 2);
        assert_eq!(series(&records, 1).len(), 1);
        assert!(series(&records, 3).is_empty());

        let e = read(&p, "cornell.dae").unwrap_err();
        assert!(e.contains("no record for scene 'cornell.dae'"), "{e}");
        assert!(e.contains("CBbunny.dae, CBspheres.dae"), "{e}");
        std::fs::remove_file(&p).unwrap();

        let bad = temp_file("bad.jsonl", &format!("{LINE}\n\n{}\n", &LINE[..40]));
        let e = read(&bad, "CBbunny.dae").unwrap_err();
        assert!(e.starts_with(&format!("{}:3: column", bad.display())), "{e}");
        std::fs::remove_file(&bad).unwrap();

        let missing = std::env::temp_dir().join("pt-peer-no-such-file.jsonl");
        let e = read(&missing, "CBbunny.dae").unwrap_err();
        assert!(e.starts_with(&missing.display().to_string()), "{e}");
        let empty = temp_file("empty.jsonl", "");
        let e = read(&empty, "CBbunny.dae").unwrap_err();
        assert!(e.contains("no record") && e.contains("0 records"), "{e}");
        std::fs::remove_file(&empty).unwrap();
    }
}
