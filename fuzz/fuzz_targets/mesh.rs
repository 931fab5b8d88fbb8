//! The mesh readers: glTF (JSON), GLB, OBJ and PLY, chosen by the input's
//! first byte so that one corpus feeds all four.
#![no_main]

#[path = "input.rs"]
mod input;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&which, rest)) = data.split_first() else {
        return;
    };
    let name = ["m.gltf", "m.glb", "m.obj", "m.ply"][usize::from(which % 4)];
    let _ = hdlod::io::read_mesh(&input::file(name, rest));
});
