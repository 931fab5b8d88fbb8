use hdlod::fixture::{Census, Scale, skyscraper};
use hdlod::scene::Class;

#[test]
fn print_counts() {
    for scale in [Scale::Tiny, Scale::Small, Scale::Paper] {
        let t = std::time::Instant::now();
        let scene = skyscraper(scale, 1);
        let c = Census::of(&scene);
        println!("{scale:?} {:?} meshes {} tasks {} days {:.0} in {:?}", c, scene.meshes.len(), scene.tasks.len(), scene.time.seconds / 86400.0, t.elapsed());
        for class in Class::ALL { println!("  {} {} {}", class.name(), c.objects(class), c.triangles(class)); }
    }
}
