//! Shared by the benchmarks: the real meshes they measure, from the test
//! data the user points `HDLOD_DATA` at (the repository does not hold them).

use std::path::PathBuf;

use hdlod::geometry::Mesh;

/// `$HDLOD_DATA/meshes/horse.ply`, or a panic that says what to set.
pub fn horse() -> Mesh {
    let data = std::env::var_os("HDLOD_DATA").unwrap_or_else(|| {
        panic!(
            "set HDLOD_DATA to the absolute path of the directory whose meshes/ holds horse.ply \
             (the classic meshes: github.com/alecjacobson/common-3d-test-models, folder data/), \
             e.g. HDLOD_DATA=$PWD/../shared/data"
        )
    });
    let path = PathBuf::from(data).join("meshes/horse.ply");
    hdlod::io::ply::read_mesh(&path).unwrap_or_else(|e| panic!("{e}"))
}
