//! The distance between two meshes as a report states it: the symmetric
//! Hausdorff bound within 1% of itself, with the mean and RMS of the
//! surface sample (`hdlod simplify`, `hdlod lod`, `hdlod bench simplify`).
//! The builder measures against budgets instead (`bound_within`).

use super::Mesh;
use super::hausdorff::{Hausdorff, HausdorffOptions, hausdorff};

/// A first pass at a tolerance of 0.1% of `a`'s size finds the scale of
/// the distance; a second one tightens the gap if the first left it wider
/// than 1% of the distance. `seed` seeds the sample of the mean and RMS.
pub fn distance(a: &Mesh, b: &Mesh, seed: u64) -> Hausdorff {
    let diagonal = a.bounds().map_or(0.0, |(lo, hi)| (hi - lo).length());
    let first = hausdorff(
        a,
        b,
        &HausdorffOptions {
            tolerance: 1e-3 * diagonal,
            seed,
        },
    );
    if first.bound - first.lower <= 0.01 * first.lower {
        return first;
    }
    hausdorff(
        a,
        b,
        &HausdorffOptions {
            tolerance: 0.01 * first.lower,
            seed,
        },
    )
}
