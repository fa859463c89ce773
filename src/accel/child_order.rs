//! The order in which a packet visits the children of a node that its lanes entered: farthest
//! first by a key per child (the entry distance of its first lane, `traverse_packet`), so that
//! the stack pops the nearest next. Two ways to the same order, chosen per packet
//! (`traverse_packet`): where the lanes head into one octant, successive nodes order their
//! children alike and an insertion sort's branches are predicted; where a closest-hit
//! packet's lanes scattered, each node's order is new, and ranks found without data-dependent
//! branches pay. Shadow packets keep the insertion sort, scattered or not (ranks measured
//! 0.93-0.98x there; PERF.md, "Paired rounds and where the branches go").

use super::wide_node::{ChildLanes, ARITY};
use crate::simd::SimdF32;

/// Writes the slots of `entered` (bit `i` for slot `i`) farthest first by their keys
/// `key_of(i)` into `order` and returns how many there are; among equal keys the lower slot
/// comes first. An insertion sort in slot order, which stores each entered slot's key in
/// `keys` as it reaches it (one pass over the slots).
#[inline(always)]
pub(super) fn by_insertion(
    keys: &mut [f32; ARITY],
    key_of: impl Fn(usize) -> f32,
    entered: u32,
    order: &mut [u8; ARITY],
) -> usize {
    let (mut bits, mut k) = (entered, 0);
    while bits != 0 {
        let i = bits.trailing_zeros() as usize % ARITY; // below ARITY: no bounds check
        bits &= bits - 1;
        keys[i] = key_of(i);
        let mut j = k;
        while j > 0 && keys[order[j - 1] as usize % ARITY] < keys[i] {
            order[j] = order[j - 1];
            j -= 1;
        }
        order[j] = i as u8;
        k += 1;
    }
    k
}

/// The order of `by_insertion`, each slot's place found as the number of entered slots
/// farther than it plus the lower ones at the same key, with one 8-wide comparison per slot
/// and no data-dependent branch. Keys of entered slots must not be NaN (an entered box's
/// entry distance compares); the others are ignored.
#[inline(always)]
pub(super) fn by_rank(keys: &[f32; ARITY], entered: u32, order: &mut [u8; ARITY]) -> usize {
    let all = ChildLanes::new(*keys);
    let mut bits = entered;
    while bits != 0 {
        // Slots and places are below `ARITY` (the remainders tell the compiler so).
        let i = bits.trailing_zeros() as usize % ARITY;
        bits &= bits - 1;
        let key = <ChildLanes as SimdF32>::splat(keys[i]);
        let farther = key.simd_lt(all).bitmask() & entered;
        let tied_before = all.simd_eq(key).bitmask() & entered & ((1 << i) - 1);
        order[(farther.count_ones() + tied_before.count_ones()) as usize % ARITY] = i as u8;
    }
    entered.count_ones() as usize
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampler::Pcg32;

    /// The insertion order, as a list: the reference for both.
    fn reference(keys: &[f32; ARITY], entered: u32) -> Vec<u8> {
        let mut order: Vec<u8> = Vec::new();
        for i in (0..ARITY).filter(|i| entered & (1 << i) != 0) {
            let j = order.iter().position(|&o| keys[o as usize] < keys[i]).unwrap_or(order.len());
            order.insert(j, i as u8);
        }
        order
    }

    #[test]
    fn both_orders_are_the_reference_order_with_ties() {
        let mut rng = Pcg32::new(5, 9);
        for round in 0..2000 {
            // Few distinct values, so that ties are common (rays starting inside several boxes
            // enter them all at t_min), and stale garbage in the slots not entered.
            let mut keys: [f32; ARITY] = std::array::from_fn(|_| match round % 3 {
                0 => (rng.next_f32() * 4.0).floor() - 1.0,
                1 => rng.next_f32() * 100.0,
                _ => f32::from_bits(rng.next_u32() & 0x7f7f_ffff),
            });
            let entered = rng.next_u32() & 0xff;
            if round % 5 == 4 {
                for (i, key) in keys.iter_mut().enumerate() {
                    if entered & (1 << i) == 0 {
                        *key = f32::NAN;
                    }
                }
            }
            let want = reference(&keys, entered);
            let mut ranked = [u8::MAX; ARITY];
            let k = by_rank(&keys, entered, &mut ranked);
            assert_eq!(ranked[..k], want[..], "ranks: keys {keys:?}, entered {entered:#b}");
            // The insertion sort stores the keys it reads: garbage in, the keys out.
            let mut stored = [f32::NAN; ARITY];
            let mut sorted = [u8::MAX; ARITY];
            let k = by_insertion(&mut stored, |i| keys[i], entered, &mut sorted);
            assert_eq!(sorted[..k], want[..], "insertion: keys {keys:?}, entered {entered:#b}");
        }
    }
}
