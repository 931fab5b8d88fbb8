//! `hdlod export-tiles TREE --time T --out DIR [--max-bytes N] [--status]`:
//! the time slice that `GET .../tiles/tileset.json?time=T` serves, on disk:
//! `DIR/tileset.json`, `DIR/tilesets/{id}.json` (external tilesets) and
//! the content: `DIR/content/{cluster}.glb` with each element's id, name,
//! class, storey and task (and with `--status` its task status and look at
//! T) as per-feature properties when the tree has object tables, else
//! `DIR/geometry/{hash}.glb` copied from the tree (flat, whatever the
//! tree's layout: the tileset's URIs name them so); a skinned cluster's
//! posed at T, `DIR/content/{seconds}/{cluster}.glb`. Written
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

/// The content GLBs `tile` and its subtree name, relative to the export's
/// directory (an external file's URIs start one directory down).
fn collect(tile: &Tile, external: bool, files: &mut BTreeSet<String>, tiles: &mut usize) {
    *tiles += 1;
    if let Some(c) = &tile.content
        && c.uri.ends_with(".glb")
    {
        let uri = if external {
            c.uri.strip_prefix("../").unwrap_or(&c.uri)
        } else {
            &c.uri
        };
        files.insert(uri.to_owned());
    }
    for child in &tile.children {
        collect(child, external, files, tiles);
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
    fs::create_dir_all(&sub).with_context(|| sub.display().to_string())?;
    let mut files = BTreeSet::new();
    let mut tiles = 0;
    write_json(&tmp.join("tileset.json"), &slice.root)?;
    collect(&slice.root.root, false, &mut files, &mut tiles);
    for (id, tileset) in &slice.external {
        write_json(&sub.join(format!("{id}.json")), tileset)?;
        collect(&tileset.root, true, &mut files, &mut tiles);
    }
    let default = Profile::default();
    for file in &files {
        let to = tmp.join(file);
        if let Some(dir) = to.parent() {
            fs::create_dir_all(dir).with_context(|| dir.display().to_string())?;
        }
        let name = file
            .rsplit('/')
            .next()
            .unwrap_or(file)
            .trim_end_matches(".glb");
        match &tree.objects {
            Some(tables) => {
                let id: u32 = name.parse().context("content files are named by cluster")?;
                let hash = tree
                    .geometry_of(id)
                    .context("a tile with content has geometry")?;
                let state = status.then(|| content::State {
                    profile: tables.appearance().unwrap_or(&default),
                    t: slice.time,
                });
                let glb = content::cluster(
                    tree,
                    tables,
                    id,
                    &tree.geometry_file(tree_dir, &hash),
                    Some(slice.time),
                    state,
                )?;
                fs::write(&to, glb).with_context(|| to.display().to_string())?;
            }
            None if file.starts_with(&format!("{CONTENT}/")) => anyhow::bail!(
                "{file}: a skinned cluster's posed content needs the tree's object tables \
                 (objects.json)"
            ),
            None => {
                let from = tree.geometry_file(tree_dir, name);
                fs::copy(&from, &to).with_context(|| from.display().to_string())?;
            }
        }
    }
    println!(
        "{} tiles, {} external tilesets, {} content files",
        tiles - slice.external.len(),
        slice.external.len(),
        files.len()
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
        posed_dir: format!("{CONTENT}/{t}"),
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
