//! Writes the synthetic sample tree (`hdlod::tree::sample`):
//! `cargo run -p hdlod --example sample_tree -- OUT [FLOORS] [SEED]`.

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let out = args
        .next()
        .ok_or("usage: sample_tree OUT [FLOORS] [SEED]")?;
    let floors = args.next().map(|f| f.parse()).transpose()?.unwrap_or(20);
    let seed = args.next().map(|s| s.parse()).transpose()?.unwrap_or(1);
    let tree = hdlod::tree::sample::write_sample_tree(std::path::Path::new(&out), seed, floors)?;
    println!(
        "{out}: scene {:?}, {} clusters",
        tree.scene,
        tree.clusters.len()
    );
    Ok(())
}
