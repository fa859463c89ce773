//! The order in which a packet visits the children of a node that its lanes entered: farthest
//! first by a key per child (the entry distance of its first lane, `traverse_packet`), so that
//! the stack pops the nearest next.

use super::wide_node::{ChildLanes, ARITY};
use crate::simd::SimdF32;

/// Writes the slots of `entered` (bit `i` for slot `i`) farthest first by `keys` into
/// `order` and returns how many there are; among equal keys the lower slot comes first, as an
/// insertion sort in slot order places them. Each slot's place is the number of entered slots
/// farther than it plus the lower ones at the same key, found with one 8-wide comparison per
/// slot: the insertion sort's data-dependent branches were a quarter of a `-m 5` render's
/// mispredicted branches in closest-hit packets (PERF.md, "Paired rounds and where the branches
/// go"). Keys of entered slots must not be NaN (an entered box's entry distance compares); the
/// others are ignored.
#[inline(always)]
pub(super) fn farthest_first(keys: &[f32; ARITY], entered: u32, order: &mut [u8; ARITY]) -> usize {
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

    /// The order an insertion sort in slot order gives (the packets' order before the ranks).
    fn by_insertion(keys: &[f32; ARITY], entered: u32) -> Vec<u8> {
        let mut order: Vec<u8> = Vec::new();
        for i in (0..ARITY).filter(|i| entered & (1 << i) != 0) {
            let j = order.iter().position(|&o| keys[o as usize] < keys[i]).unwrap_or(order.len());
            order.insert(j, i as u8);
        }
        order
    }

    #[test]
    fn ranks_give_the_insertion_order_with_ties() {
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
            let mut order = [u8::MAX; ARITY];
            let k = farthest_first(&keys, entered, &mut order);
            assert_eq!(order[..k], by_insertion(&keys, entered)[..], "keys {keys:?}, {entered:#b}");
        }
    }
}
