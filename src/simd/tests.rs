//! Unit tests of the lane types and the gather.

use super::*;

fn masks<V: SimdF32>() {
    for n in 0..=V::W {
        let m = V::first_lanes(n);
        assert_eq!(m.bitmask(), (1u32 << n) - 1);
        assert_eq!(V::from_bitmask(m.bitmask()).bitmask(), m.bitmask());
    }
    let a = V::splat(1.0);
    let b = V::splat(2.0);
    assert_eq!(a.simd_lt(b).bitmask(), (1u32 << V::W) - 1);
    assert_eq!(V::select(V::first_lanes(1), a, b).lane(0), 1.0);
    assert_eq!(V::select(V::first_lanes(1), a, b).lane(1), 2.0);
}

fn columns<V: SimdF32>() {
    let rows: Vec<[f32; 8]> =
        (0..V::W - 1).map(|i| std::array::from_fn(|k| (10 * i + k) as f32)).collect();
    let cols = V::columns8(rows.len(), |i| rows[i]);
    for (k, col) in cols.iter().enumerate() {
        for i in 0..V::W {
            let want = if i < rows.len() { (10 * i + k) as f32 } else { 0.0 };
            assert_eq!(col.lane(i), want, "column {k} lane {i}");
        }
    }
}

fn row_minima<V: SimdF32>() {
    let rows: [V; 8] = std::array::from_fn(|i| {
        let vals: Vec<f32> = (0..V::W).map(|k| ((7 * i + 3 * k) % 11) as f32 - i as f32).collect();
        V::load(&vals)
    });
    let (lo, hi) = (V::min_of_rows(rows), V::max_of_rows(rows));
    for (i, r) in rows.iter().enumerate() {
        let want = (0..V::W).map(|k| r.lane(k)).fold(f32::INFINITY, f32::min);
        assert_eq!(lo[i], want, "row {i}");
        let want = (0..V::W).map(|k| r.lane(k)).fold(f32::NEG_INFINITY, f32::max);
        assert_eq!(hi[i], want, "row {i}");
    }
}

#[test]
fn row_minima_at_every_width() {
    row_minima::<f32x4>();
    row_minima::<f32x8>();
    row_minima::<F32x16>();
}

fn rows<V: SimdF32>() {
    let rows: Vec<[f32; 8]> =
        (0..V::W).map(|i| std::array::from_fn(|k| (10 * i + k) as f32)).collect();
    let mut back = vec![[0.0; 8]; V::W];
    V::rows8(V::columns8(V::W, |i| rows[i]), &mut back);
    assert_eq!(back, rows);
}

#[test]
fn gathers_read_the_indexed_values_and_refuse_indices_out_of_range() {
    let base: Vec<f32> = (0..100).map(|i| i as f32 * 0.5).collect();
    let index: [u32; 16] = std::array::from_fn(|i| (i as u32 * 37) % 100);
    let mut out = [0.0f32; 16];
    assert!(gather16(&base, &index, &mut out));
    assert_eq!(out, index.map(|i| base[i as usize]));
    let words: Vec<u32> = (0..100).map(|i| i * 7).collect();
    let mut got = [0u32; 16];
    assert!(gather16(&words, &index, &mut got));
    assert_eq!(got, index.map(|i| words[i as usize]));
    let mut bad = index;
    bad[15] = 100;
    let before = out;
    assert!(!gather16(&base, &bad, &mut out));
    assert_eq!(out, before);
}

#[test]
fn rows_invert_columns_at_every_width() {
    rows::<f32x4>();
    rows::<f32x8>();
    rows::<F32x16>();
}

#[test]
fn columns_transpose_rows_at_both_widths() {
    columns::<f32x4>();
    columns::<f32x8>();
    columns::<F32x16>();
}

#[test]
fn masks_round_trip_at_both_widths() {
    masks::<f32x4>();
    masks::<f32x8>();
    masks::<F32x16>();
}
