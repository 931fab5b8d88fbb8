//! The cut protocol, one for every client: the request (`request.rs`: from
//! a JSON body, query pairs or `hdlod cut`'s flags, then prepared against
//! the tree), the cut run into reused buffers ([`run`]), and the answer
//! (`answer.rs`). `POST`/`GET .../cut`, the WebSocket stream, `hdlod cut`
//! and the tiles' times (the API's and `hdlod export-tiles`) all go through
//! it; errors are a [`ProtocolError`] naming the field at fault. The HDLOD
//! work is `hdlod::tree::cut`.

mod answer;
mod error;
mod request;

use std::time::Instant;

use hdlod::tree::cut::{Lod, Presence, cut_into, present_leaves_into};
use hdlod::tree::{Cut, Tree, View};

pub use answer::{
    Fragments, answer, scene_path, segment, stats_out, write_answer, write_number, write_transform,
};
pub use error::ProtocolError;
pub use request::{
    CutRequest, Flags, parse_flags, parse_json, parse_query, parse_time, parse_time_query, prepare,
    resolve_time, within_period,
};

/// Runs the cut (or, without levels of detail, takes every present leaf)
/// into reused buffers and returns its duration in microseconds.
pub fn run(
    tree: &Tree,
    view: &View,
    t: f64,
    (presence, lod): (Presence, Lod),
    cut: &mut Cut,
    stack: &mut Vec<u32>,
) -> f64 {
    let start = Instant::now();
    match lod {
        Lod::Hdlod => cut_into(tree, view, t, presence, cut, stack),
        Lod::None => present_leaves_into(tree, t, presence, cut, stack),
    }
    start.elapsed().as_secs_f64() * 1e6
}
