//! `hdlod index TREE`: writes the serving indexes of a tree from its JSON
//! files (`clusters.bin` from `clusters.json`; `objects.bin` from
//! `objects.json` when it has object tables): for trees built before the
//! indexes, whose cluster index is of an earlier version (the migration
//! to version 3, which stores the counts and baseline and the clusters'
//! triangles in the node records), or whose indexes are damaged.
//! A running server reloads the tree when they appear.

use std::path::PathBuf;

use anyhow::Context;
use hdlod::tree::format::{INDEX_FILE, OBJECTS_INDEX_FILE};

#[derive(clap::Args)]
pub struct Args {
    /// The tree directory (an hdlod tree).
    tree: PathBuf,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    hdlod::tree::store::write_index(&args.tree)
        .with_context(|| format!("cannot index the tree {}", args.tree.display()))?;
    let objects = args.tree.join(OBJECTS_INDEX_FILE);
    if objects.exists() {
        println!("wrote {}", objects.display());
    }
    println!("wrote {}", args.tree.join(INDEX_FILE).display());
    Ok(())
}
