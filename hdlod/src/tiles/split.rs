//! Splitting a tileset into external tilesets (OGC 3D Tiles 1.1, "External
//! tilesets") so that no JSON file passes `Options::max_bytes`.
//!
//! Bottom-up: a tile's inline size is its own JSON plus its children's
//! inline sizes; where that passes the budget, its largest children move to
//! files of their own until it fits. A moved child leaves a stub behind:
//! the same bounding volume, error and transform, and as content the URI of
//! the external tileset, whose root is the child without its transform (the
//! stub's transform applies to the external tileset, as for any content).
//! All external tilesets live in one directory, so a stub's URI is
//! `{subtileset_dir}/{id}.json` from the root file and `{id}.json` from
//! another external file, and content URIs gain a `../` when a tile moves
//! down into that directory.

use std::cmp::Reverse;
use std::collections::BTreeMap;

use super::tileset::{Asset, Content, Options, Refine, Tile, Tileset};

/// Room left in each file for the tileset's own fields (asset, extras).
const WRAPPER_BYTES: usize = 512;

/// `,"children":[]`: what a tile's JSON gains with its first child.
const CHILDREN_BYTES: usize = 14;

/// A moved tile's content URIs each gain `../`: counted in advance so that
/// the sizes hold after the move.
const RELOCATION_BYTES: usize = 3;

struct Splitter<'a> {
    options: &'a Options,
    asset: &'a Asset,
    budget: usize,
    out: BTreeMap<u32, Tileset>,
}

fn json_len<T: serde::Serialize>(value: &T) -> usize {
    serde_json::to_vec(value).map_or(0, |v| v.len())
}

impl Splitter<'_> {
    /// The tile's size in its file once its subtree fits, moving children
    /// out where it does not.
    fn fit(&mut self, tile: &mut Tile) -> usize {
        let sizes: Vec<usize> = tile.children.iter_mut().map(|c| self.fit(c)).collect();
        let children = std::mem::take(&mut tile.children);
        let own = json_len(tile) + RELOCATION_BYTES;
        tile.children = children;
        if sizes.is_empty() {
            return own;
        }
        let mut total = own + CHILDREN_BYTES + sizes.len() - 1 + sizes.iter().sum::<usize>();
        let mut order: Vec<usize> = (0..sizes.len()).collect();
        order.sort_by_key(|&i| Reverse(sizes[i]));
        for i in order {
            if total <= self.budget {
                break;
            }
            let stub = self.move_out(&mut tile.children[i]);
            total = total - sizes[i] + stub;
        }
        total
    }

    /// Moves `tile` to an external tileset and leaves its stub in its
    /// place; returns the stub's size.
    fn move_out(&mut self, tile: &mut Tile) -> usize {
        let id = tile
            .extras
            .expect("every tile of a time slice names its cluster")
            .cluster;
        let stub = Tile {
            bounding_volume: tile.bounding_volume.clone(),
            geometric_error: tile.geometric_error,
            refine: None,
            transform: tile.transform.take(),
            content: Some(Content {
                uri: format!("{}/{id}.json", self.options.subtileset_dir),
            }),
            children: Vec::new(),
            extras: tile.extras,
        };
        let size = json_len(&stub) + RELOCATION_BYTES;
        let mut moved = std::mem::replace(tile, stub);
        moved.refine = Some(Refine::Replace);
        self.relocate(&mut moved);
        self.out.insert(
            id,
            Tileset {
                asset: self.asset.clone(),
                geometric_error: moved.geometric_error,
                root: moved,
                extras: None,
            },
        );
        size
    }

    /// Rewrites the URIs of a subtree that moves from the root file's
    /// directory into the external tilesets' one (stubs end the subtree).
    fn relocate(&self, tile: &mut Tile) {
        if let Some(content) = &mut tile.content {
            let prefix = format!("{}/", self.options.subtileset_dir);
            content.uri = match content.uri.strip_prefix(&prefix) {
                Some(rest) => rest.to_owned(),
                None => format!("../{}", content.uri),
            };
        }
        for child in &mut tile.children {
            self.relocate(child);
        }
    }
}

/// Splits `root` in place; returns the external tilesets by cluster id.
pub(super) fn split(
    root: &mut Tileset,
    options: &Options,
    asset: &Asset,
) -> BTreeMap<u32, Tileset> {
    let mut splitter = Splitter {
        options,
        asset,
        budget: options.max_bytes.saturating_sub(WRAPPER_BYTES),
        out: BTreeMap::new(),
    };
    splitter.fit(&mut root.root);
    splitter.out
}
