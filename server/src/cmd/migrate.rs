//! `hdlod migrate TREE`: brings a tree to the current format in place
//! (`hdlod::tree::migrate`): an `hdlod-tree/1` tree's geometry moves into
//! its 256 shards and its manifest says `hdlod-tree/2`; its serving indexes
//! are written if missing or of an earlier version. Safe to interrupt and
//! run again; a current tree is left as it is. A running server reloads the
//! tree when its manifest changes.

use std::path::PathBuf;

use anyhow::Context;

#[derive(clap::Args)]
pub struct Args {
    /// The tree directory (an hdlod tree).
    tree: PathBuf,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let clock = std::time::Instant::now();
    let done = hdlod::tree::migrate::migrate(&args.tree)
        .with_context(|| format!("cannot migrate the tree {}", args.tree.display()))?;
    let tree = args.tree.display();
    if !done.changed() {
        println!(
            "{tree} is already {}: nothing to do",
            hdlod::tree::format::FORMAT
        );
        return Ok(());
    }
    if done.manifest {
        println!(
            "{tree}: {} -> {}, {} geometry files linked into their shards",
            done.from,
            hdlod::tree::format::FORMAT,
            done.linked
        );
    }
    if done.removed > 0 {
        println!("{tree}: {} flat geometry files removed", done.removed);
    }
    if done.indexes {
        println!("{tree}: serving indexes written");
    }
    println!("done in {:.2} s", clock.elapsed().as_secs_f64());
    Ok(())
}
