use hdlod::geometry::{HausdorffOptions, SimplifyOptions, hausdorff, simplify};
fn main() {
    let p = std::env::args().nth(1).unwrap();
    let m = hdlod::io::gltf::read_mesh(std::path::Path::new(&p)).unwrap();
    for prune in [false, true] {
        for e in [2.0f32, 1.0, 0.5, 0.25, 0.12] {
            let s = simplify(&m, &SimplifyOptions { max_error: e, target_triangles: None, prune });
            let h = hausdorff(&s.mesh, &m, &HausdorffOptions { tolerance: 0.05, seed: 0 });
            println!("prune {prune} e {e}: {:?} {} -> {} D_H {:.3} (ab {:.3} ba {:.3})", s.strategy, m.triangle_count(), s.triangles, h.bound, h.ab, h.ba);
        }
    }
}
