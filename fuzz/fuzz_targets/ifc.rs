//! The IFC reader: STEP text (or an .ifczip) through the mesher, the
//! styles, storeys, placements and checks.
#![no_main]

#[path = "input.rs"]
mod input;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = hdlod::import::ifc::read(&input::file("m.ifc", data));
});
