//! 3D Hilbert keys: the order in which the builder visits representatives,
//! so that consecutive representatives are spatial neighbours.
//!
//! Reference: J. Skilling, "Programming the Hilbert curve", AIP Conference
//! Proceedings 707 (2004): the axes-to-transpose transform. Written here
//! because it is twenty lines and the crates that offer it (lindel, hilbert)
//! are unmaintained or pull in big-integer arithmetic for a 63-bit key.

use glam::Vec3;

/// Bits per axis: 3 x 21 = 63 bits fit a `u64`.
const BITS: u32 = 21;

/// The Hilbert index of integer coordinates, each below `2^BITS`.
pub fn hilbert_index(mut x: [u32; 3]) -> u64 {
    let m = 1u32 << (BITS - 1);
    // Inverse undo of Skilling's AxestoTranspose.
    let mut q = m;
    while q > 1 {
        let p = q - 1;
        for i in 0..3 {
            if x[i] & q != 0 {
                x[0] ^= p;
            } else {
                let t = (x[0] ^ x[i]) & p;
                x[0] ^= t;
                x[i] ^= t;
            }
        }
        q >>= 1;
    }
    // Gray encode.
    for i in 1..3 {
        x[i] ^= x[i - 1];
    }
    let mut t = 0;
    let mut q = m;
    while q > 1 {
        if x[2] & q != 0 {
            t ^= q - 1;
        }
        q >>= 1;
    }
    for v in &mut x {
        *v ^= t;
    }
    // Interleave the transposed bits, most significant first.
    let mut key = 0u64;
    for b in (0..BITS).rev() {
        for v in x {
            key = (key << 1) | u64::from((v >> b) & 1);
        }
    }
    key
}

/// The Hilbert key of a point inside the box `[lo, hi]`.
pub fn hilbert_key(p: Vec3, lo: Vec3, hi: Vec3) -> u64 {
    let extent = (hi - lo).max(Vec3::splat(f32::MIN_POSITIVE));
    let max = ((1u32 << BITS) - 1) as f32;
    let q = ((p - lo) / extent).clamp(Vec3::ZERO, Vec3::ONE) * max;
    hilbert_index([q.x as u32, q.y as u32, q.z as u32])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On a 2^k grid the Hilbert order is a bijection whose consecutive cells
    /// are face neighbours: the defining property of the curve.
    #[test]
    fn consecutive_cells_are_neighbours() {
        let n = 8u32;
        let shift = BITS - 3; // scale the 8^3 grid up to the full key range
        let mut cells: Vec<(u64, [u32; 3])> = Vec::new();
        for x in 0..n {
            for y in 0..n {
                for z in 0..n {
                    let key = hilbert_index([x << shift, y << shift, z << shift]);
                    cells.push((key, [x, y, z]));
                }
            }
        }
        cells.sort();
        cells.dedup_by_key(|c| c.0);
        assert_eq!(cells.len(), 512);
        for w in cells.windows(2) {
            let d: u32 = (0..3).map(|i| w[0].1[i].abs_diff(w[1].1[i])).sum();
            assert_eq!(d, 1, "{:?} -> {:?}", w[0].1, w[1].1);
        }
    }
}
