//! The schedule importers: Primavera P6 XER and XML, Microsoft Project
//! XML, element-task CSV, as-built logs and spreadsheets, chosen by the
//! input's first byte so that one corpus feeds all.
#![no_main]

#[path = "input.rs"]
mod input;

use hdlod::import::{actual, links_csv, msproject, pmxml, xer, xlsx};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&which, rest)) = data.split_first() else {
        return;
    };
    match which % 6 {
        0 => drop(xer::read(&input::file("s.xer", rest), None)),
        1 => drop(pmxml::read(&input::file("s.xml", rest), None)),
        2 => drop(msproject::read(&input::file("s.xml", rest))),
        3 => drop(links_csv::read(&input::file("s.csv", rest))),
        4 => drop(actual::read(&input::file("a.csv", rest))),
        _ => drop(xlsx::read(
            &input::file("s.xlsx", rest),
            &xlsx::Mapping::default(),
        )),
    }
});
