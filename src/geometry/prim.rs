//! The primitive id carried by `Hit::prim`: a scene triangle index, or a sphere index with
//! `SPHERE_BIT` set. The acceleration structure makes ids, shading and light sampling read
//! them; this module is the one place that knows the encoding.

/// Sphere ids carry this bit; the low bits are the sphere index.
pub const SPHERE_BIT: u32 = 1 << 31;

/// The id of scene triangle `index` (below `SPHERE_BIT`).
#[inline]
pub fn triangle(index: u32) -> u32 {
    debug_assert!(index & SPHERE_BIT == 0);
    index
}

/// The id of scene sphere `index`.
#[inline]
pub fn sphere(index: u32) -> u32 {
    SPHERE_BIT | index
}

/// Whether `prim` names a sphere (otherwise a triangle).
#[inline]
pub fn is_sphere(prim: u32) -> bool {
    prim & SPHERE_BIT != 0
}

/// The sphere index of a sphere id.
#[inline]
pub fn sphere_index(prim: u32) -> u32 {
    prim & !SPHERE_BIT
}

/// The triangle index of a triangle id.
#[inline]
pub fn triangle_index(prim: u32) -> u32 {
    debug_assert!(!is_sphere(prim));
    prim
}

#[test]
fn ids_round_trip() {
    assert!(!is_sphere(triangle(7)) && triangle_index(triangle(7)) == 7);
    assert!(is_sphere(sphere(3)) && sphere_index(sphere(3)) == 3);
    assert!(is_sphere(sphere(0)) && sphere(0) != triangle(0));
}
