//! The cut request parser of the API and the stream (the server's
//! `protocol/request.rs`, compiled in here as it is), from a JSON body and
//! from query pairs, and the camera it gives checked into a view.
#![no_main]

#[path = "../../server/src/protocol/error.rs"]
mod error;
#[path = "../../server/src/protocol/request.rs"]
#[allow(dead_code)]
mod request;

use error::ProtocolError;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(r) = request::parse_json(data) {
        let _ = hdlod::tree::View::new(&r.camera, r.viewport, r.pixel_error, glam::DVec3::Y);
    }
    let text = String::from_utf8_lossy(data);
    let pairs: Vec<(String, String)> = text
        .split('&')
        .map(|p| {
            let (k, v) = p.split_once('=').unwrap_or((p, ""));
            (k.to_owned(), v.to_owned())
        })
        .collect();
    if let Ok(r) = request::parse_query(&pairs) {
        let _ = hdlod::tree::View::new(&r.camera, r.viewport, r.pixel_error, glam::DVec3::Y);
    }
    let _: Result<_, ProtocolError> = request::parse_time_query(&pairs);
});
