//! `hdlod index TREE`: writes the serving index (`clusters.bin`) of a tree
//! from its `clusters.json`: for trees built before the index, or whose
//! index is damaged. A running server reloads the tree when it appears.

use std::path::PathBuf;

use anyhow::Context;

#[derive(clap::Args)]
pub struct Args {
    /// The tree directory (hdlod-tree/1).
    tree: PathBuf,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    hdlod::tree::store::write_index(&args.tree)
        .with_context(|| format!("cannot index the tree {}", args.tree.display()))?;
    println!(
        "wrote {}",
        args.tree.join(hdlod::tree::format::INDEX_FILE).display()
    );
    Ok(())
}
