//! `hdlod export-tiles TREE --time T --out DIR [--max-bytes N] [--status]`:
//! the time slice that `GET .../tiles/tileset.json?time=T` serves, on disk:
//! `DIR/tileset.json`, `DIR/tilesets/{id}.json` (external tilesets) and
//! the content: `DIR/content/{cluster}.glb` with each element's id, name,
//! class, storey and task (and with `--status` its task status and look at
//! T) as per-feature properties when the tree has object tables, else
//! `DIR/geometry/{hash}.glb` copied from the tree (flat, whatever the
//! tree's layout: the tileset's URIs name them so). Written
//! into a temporary sibling directory first and renamed into place, so DIR
//! is either the old export or the whole new one.

use std::collections::BTreeSet;
use std::fs;
use std::path::{Path, PathBuf};

use anyhow::Context;
use hdlod::scene::Profile;
use hdlod::tiles::{
    ContentNames, DEFAULT_MAX_BYTES, Frame, Options, Tile, Tileset, content, time_slice,
};
use hdlod::tree::Tree;
use hdlod::tree::format::GEOMETRY_DIR;

use crate::protocol::{parse_time, resolve_time};

const SUBTILESETS: &str = "tilesets";
/// The slice's own content, when the tree has object tables.
const CONTENT: &str = "content";

#[derive(clap::Args)]
pub struct Args {
    /// A tree directory (an hdlod tree).
    tree: PathBuf,
    /// Seconds since the scene's start, or an ISO 8601 date.
    #[arg(long)]
    time: String,
    /// The directory to write (replaced if it exists).
    #[arg(long)]
    out: PathBuf,
    /// Largest JSON file in bytes; larger slices move subtrees to external
    /// tilesets.
    #[arg(long, default_value_t = DEFAULT_MAX_BYTES)]
    max_bytes: usize,
    /// `earth`: a georeferenced scene's root placed on the globe (ECEF);
    /// `local`: its own frame, for engines in local coordinates.
    #[arg(long, value_enum, default_value_t = FrameArg::Earth)]
    frame: FrameArg,
    /// Each element's task status, deviation and look at T in the content
    /// too (content then made for this one date).
    #[arg(long)]
    status: bool,
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum FrameArg {
    Earth,
    Local,
}

fn collect(tile: &Tile, hashes: &mut BTreeSet<String>, tiles: &mut usize) {
    *tiles += 1;
    if let Some(c) = &tile.content
        && let Some(file) = c.uri.rsplit('/').next().filter(|f| f.ends_with(".glb"))
    {
        hashes.insert(file.to_owned());
    }
    for child in &tile.children {
        collect(child, hashes, tiles);
    }
}

fn write_json(path: &Path, tileset: &Tileset) -> anyhow::Result<()> {
    let bytes = serde_json::to_vec(tileset)?;
    fs::write(path, bytes).with_context(|| path.display().to_string())
}

/// Writes everything into `tmp`.
fn write(
    tmp: &Path,
    tree_dir: &Path,
    tree: &Tree,
    slice: &hdlod::tiles::TimeSlice,
    status: bool,
) -> anyhow::Result<()> {
    let sub = tmp.join(SUBTILESETS);
    let own = tree.objects.is_some();
    let geometry = tmp.join(if own { CONTENT } else { GEOMETRY_DIR });
    for dir in [&sub, &geometry] {
        fs::create_dir_all(dir).with_context(|| dir.display().to_string())?;
    }
    let mut hashes = BTreeSet::new();
    let mut tiles = 0;
    write_json(&tmp.join("tileset.json"), &slice.root)?;
    collect(&slice.root.root, &mut hashes, &mut tiles);
    for (id, tileset) in &slice.external {
        write_json(&sub.join(format!("{id}.json")), tileset)?;
        collect(&tileset.root, &mut hashes, &mut tiles);
    }
    let default = Profile::default();
    for file in &hashes {
        let to = geometry.join(file);
        match &tree.objects {
            Some(tables) => {
                let id: u32 = file
                    .trim_end_matches(".glb")
                    .parse()
                    .context("content files are named by cluster")?;
                let hash = tree
                    .geometry_of(id)
                    .context("a tile with content has geometry")?;
                let (mesh, texture) =
                    hdlod::io::read_textured_mesh(&tree.geometry_file(tree_dir, &hash))?;
                let state = status.then(|| content::State {
                    profile: tables.appearance().unwrap_or(&default),
                    t: slice.time,
                });
                let glb = content::content(
                    &mesh,
                    texture.as_ref(),
                    tree.dynamic_object(id),
                    tables,
                    state,
                );
                fs::write(&to, glb).with_context(|| to.display().to_string())?;
            }
            None => {
                let hash = file.trim_end_matches(".glb");
                let from = tree.geometry_file(tree_dir, hash);
                fs::copy(&from, &to).with_context(|| from.display().to_string())?;
            }
        }
    }
    println!(
        "{} tiles, {} external tilesets, {} content files",
        tiles - slice.external.len(),
        slice.external.len(),
        hashes.len()
    );
    Ok(())
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let tree = hdlod::tree::load(&args.tree)?;
    let t = resolve_time(&tree, "--time", &parse_time(&args.time))?;
    let (dir, names) = match tree.objects {
        Some(_) => (CONTENT, ContentNames::Cluster),
        None => (GEOMETRY_DIR, ContentNames::Geometry),
    };
    let options = Options {
        max_bytes: args.max_bytes,
        content: names,
        frame: match args.frame {
            FrameArg::Earth => Frame::Earth,
            FrameArg::Local => Frame::Local,
        },
        ..Options::new(dir, SUBTILESETS)
    };
    let slice = time_slice(&tree, t, &options)?;

    let out = &args.out;
    let name = out
        .file_name()
        .with_context(|| format!("--out {}: names no directory", out.display()))?
        .to_string_lossy()
        .into_owned();
    if let Some(parent) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
        fs::create_dir_all(parent).with_context(|| parent.display().to_string())?;
    }
    let pid = std::process::id();
    let tmp = out.with_file_name(format!(".{name}.tmp-{pid}"));
    let old = out.with_file_name(format!(".{name}.old-{pid}"));
    if let Err(e) = write(&tmp, &args.tree, &tree, &slice, args.status) {
        let _ = fs::remove_dir_all(&tmp);
        return Err(e);
    }
    let had_old = out.exists();
    if had_old {
        fs::rename(out, &old).with_context(|| out.display().to_string())?;
    }
    if let Err(e) = fs::rename(&tmp, out) {
        if had_old {
            let _ = fs::rename(&old, out);
        }
        let _ = fs::remove_dir_all(&tmp);
        return Err(e).with_context(|| out.display().to_string());
    }
    if had_old {
        fs::remove_dir_all(&old).with_context(|| old.display().to_string())?;
    }
    Ok(())
}
