//! Spreadsheet task lists (`.xlsx`): columns by their usual names or by the
//! rules file's mapping, date cells and dates as text, links, custom fields
//! for the rules, and every bad input named by sheet, cell and column. The
//! workbooks are written here, in the least that Excel and calamine read:
//! the package's and the workbook's relationships, a workbook, a style sheet with a date format and one
//! sheet of inline strings and numbers.
#![cfg(feature = "ifc")]

use std::io::Write;
use std::path::{Path, PathBuf};

use hdlod::import::{Options, Source, import, read_schedule};
use hdlod::scene::LinkType;
use hdlod::time::parse_date;

/// A cell: text, or a date (an Excel serial day in a date-styled cell).
#[derive(Clone)]
enum Cell<'a> {
    Text(&'a str),
    Date(f64),
}
use Cell::{Date, Text};

fn column(c: usize) -> char {
    (b'A' + c as u8) as char
}

fn workbook(dir: &Path, name: &str, sheet: &str, rows: &[Vec<Cell>]) -> PathBuf {
    let mut data = String::new();
    for (r, row) in rows.iter().enumerate() {
        data += &format!("<row r=\"{}\">", r + 1);
        for (c, cell) in row.iter().enumerate() {
            let at = format!("{}{}", column(c), r + 1);
            data += &match cell {
                Text("") => String::new(),
                Text(t) => format!("<c r=\"{at}\" t=\"inlineStr\"><is><t>{t}</t></is></c>"),
                Date(d) => format!("<c r=\"{at}\" s=\"1\"><v>{d}</v></c>"),
            };
        }
        data += "</row>";
    }
    let main = "http://schemas.openxmlformats.org/spreadsheetml/2006/main";
    let rel = "http://schemas.openxmlformats.org/officeDocument/2006/relationships";
    let parts = [
        (
            "[Content_Types].xml",
            String::from(
                "<Types xmlns=\"http://schemas.openxmlformats.org/package/2006/content-types\">\
                 <Default Extension=\"xml\" ContentType=\"application/xml\"/>\
                 <Override PartName=\"/xl/workbook.xml\" ContentType=\"application/vnd.openxmlformats-officedocument.spreadsheetml.sheet.main+xml\"/>\
                 <Override PartName=\"/xl/worksheets/sheet1.xml\" ContentType=\"application/vnd.openxmlformats-officedocument.spreadsheetml.worksheet+xml\"/>\
                 </Types>",
            ),
        ),
        (
            "_rels/.rels",
            format!(
                "<Relationships xmlns=\"http://schemas.openxmlformats.org/package/2006/relationships\">\
                 <Relationship Id=\"rId1\" Type=\"{rel}/officeDocument\" Target=\"xl/workbook.xml\"/>\
                 </Relationships>"
            ),
        ),
        (
            "xl/workbook.xml",
            format!(
                "<workbook xmlns=\"{main}\" xmlns:r=\"{rel}\"><sheets>\
                 <sheet name=\"{sheet}\" sheetId=\"1\" r:id=\"rId1\"/></sheets></workbook>"
            ),
        ),
        (
            "xl/_rels/workbook.xml.rels",
            format!(
                "<Relationships xmlns=\"http://schemas.openxmlformats.org/package/2006/relationships\">\
                 <Relationship Id=\"rId1\" Type=\"{rel}/worksheet\" Target=\"worksheets/sheet1.xml\"/>\
                 <Relationship Id=\"rId2\" Type=\"{rel}/styles\" Target=\"styles.xml\"/>\
                 </Relationships>"
            ),
        ),
        (
            "xl/styles.xml",
            format!(
                "<styleSheet xmlns=\"{main}\"><cellXfs count=\"2\"><xf numFmtId=\"0\"/>\
                 <xf numFmtId=\"22\" applyNumberFormat=\"1\"/></cellXfs></styleSheet>"
            ),
        ),
        (
            "xl/worksheets/sheet1.xml",
            format!("<worksheet xmlns=\"{main}\"><sheetData>{data}</sheetData></worksheet>"),
        ),
    ];
    let path = dir.join(name);
    let mut zip = zip::ZipWriter::new(std::fs::File::create(&path).unwrap());
    let options =
        zip::write::SimpleFileOptions::default().compression_method(zip::CompressionMethod::Stored);
    for (part, text) in parts {
        zip.start_file(part, options).unwrap();
        zip.write_all(text.as_bytes()).unwrap();
    }
    zip.finish().unwrap();
    path
}

/// 2024-01-08 08:00 as an Excel serial day (days since 1899-12-30).
const JAN8: f64 = 45299.0 + 8.0 / 24.0;

fn plan() -> Vec<Vec<Cell<'static>>> {
    vec![
        vec![
            Text("Activity ID"),
            Text("Activity Name"),
            Text("Start"),
            Text("Finish"),
            Text("Actual Start"),
            Text("Parent"),
            Text("Predecessors"),
            Text("Zone"),
            Text("Trade"),
        ],
        vec![
            Text("S"),
            Text("Shell"),
            Date(JAN8),
            Date(JAN8 + 30.0),
            Text(""),
            Text(""),
            Text(""),
            Text(""),
            Text(""),
        ],
        vec![
            Text("W1"),
            Text("Walls"),
            Date(JAN8),
            Date(JAN8 + 4.375),
            Date(JAN8 + 1.0),
            Text("S"),
            Text(""),
            Text("North"),
            Text("masonry"),
        ],
        vec![
            Text("SL1"),
            Text("Slab"),
            Text("2024-01-22T08:00:00"),
            Text("26-1-2024"),
            Text(""),
            Text("S"),
            Text("W1FS+2d"),
            Text("South"),
            Text("concrete"),
        ],
        vec![Text(""); 9],
        vec![
            Text("H"),
            Text("Handover"),
            Date(JAN8 + 60.0),
            Date(JAN8 + 60.0),
            Text(""),
            Text(""),
            Text("W1SS; SL1"),
            Text(""),
            Text(""),
        ],
    ]
}

#[test]
fn a_task_list_reads_by_its_headers() {
    let dir = tempfile::tempdir().unwrap();
    let path = workbook(dir.path(), "plan.xlsx", "Plan", &plan());
    let tasks = read_schedule(&path, &Source::default()).unwrap();
    let got: Vec<(&str, &str, Option<&str>)> = tasks
        .iter()
        .map(|t| (t.id.as_str(), t.name.as_str(), t.parent.as_deref()))
        .collect();
    assert_eq!(
        got,
        [
            ("S", "Shell", None),
            ("W1", "Walls", Some("S")),
            ("SL1", "Slab", Some("S")),
            ("H", "Handover", None)
        ]
    );
    let d = |s: &str| parse_date(s).unwrap();
    let walls = &tasks[1];
    assert_eq!(walls.start, d("2024-01-08T08:00:00"));
    assert_eq!(walls.finish, d("2024-01-12T17:00:00"));
    assert_eq!(walls.actual.start, Some(d("2024-01-09T08:00:00")));
    assert_eq!(walls.fields["Zone"], "North");
    assert_eq!(walls.fields["Trade"], "masonry");
    // Text dates: ISO, and day-first.
    assert_eq!(tasks[2].start, d("2024-01-22T08:00:00"));
    assert_eq!(tasks[2].finish, d("2024-01-26T00:00:00"));
    let links: Vec<(&str, LinkType, f64)> = tasks[3]
        .predecessors
        .iter()
        .chain(&tasks[2].predecessors)
        .map(|p| (p.task.as_str(), p.kind, p.lag / 3600.0))
        .collect();
    assert_eq!(
        links,
        [
            ("W1", LinkType::StartStart, 0.0),
            ("SL1", LinkType::FinishStart, 0.0),
            ("W1", LinkType::FinishStart, 48.0)
        ]
    );
}

#[test]
fn the_rules_file_maps_columns_and_links_by_fields() {
    let dir = tempfile::tempdir().unwrap();
    let mut rows = plan();
    rows[0][0] = Text("Code");
    rows[0][2] = Text("Begin");
    let path = workbook(dir.path(), "plan.xlsx", "Plan", &rows);
    let rules = dir.path().join("links.json");
    std::fs::write(
        &rules,
        r#"{"format": "hdlod-links/1",
            "spreadsheet": {"sheet": "Plan", "columns": {"id": "code", "start": "Begin"}},
            "rules": [
              {"name": "walls", "select": {"class": "IfcWall"}, "tasks": {"fields": {"Trade": "masonry"}}},
              {"name": "slab", "select": {"class": "IfcSlab"}, "tasks": {"fields": {"Zone": "south"}}}
            ]}"#,
    )
    .unwrap();
    let options = Options {
        name: "tiny".into(),
        schedule: Some(path),
        links: Some(rules.clone()),
        ..Options::default()
    };
    let tiny = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/ifc-tiny/tiny.ifc");
    let (scene, report) = import(std::slice::from_ref(&tiny), &options, &|_| {}).unwrap();
    let slab = scene.tasks.iter().find(|t| t.id == "SL1").unwrap();
    assert_eq!(slab.predecessors[0].task, "W1");
    assert_eq!(slab.parent.as_deref(), Some("S"));
    assert_eq!(report.rules.iter().map(|r| r.matched).sum::<usize>(), 2);
    assert_eq!(report.links, 1);

    // A column the mapping names but the sheet lacks; an unknown column.
    for (mapping, wanted) in [
        (r#"{"columns": {"id": "Nope"}}"#, "no column \"Nope\""),
        (
            r#"{"columns": {"colour": "Zone"}}"#,
            "spreadsheet.columns.colour",
        ),
        (
            r#"{"sheet": "Gantt"}"#,
            "no such sheet; the workbook has Plan",
        ),
    ] {
        std::fs::write(
            &rules,
            format!(r#"{{"format": "hdlod-links/1", "spreadsheet": {mapping}, "rules": []}}"#),
        )
        .unwrap();
        let e = import(std::slice::from_ref(&tiny), &options, &|_| {})
            .unwrap_err()
            .to_string();
        assert!(e.contains(wanted), "{wanted:?} not in {e:?}");
    }
}

#[test]
fn bad_task_lists_name_the_sheet_cell_and_column() {
    let dir = tempfile::tempdir().unwrap();
    let cases: Vec<(usize, usize, Cell<'static>, &str)> = vec![
        (2, 2, Text("next monday"), "Plan!C3 (column \"Start\")"),
        (2, 2, Date(-5.0), "Plan!C3 (column \"Start\")"),
        (2, 3, Date(2_000_000.0), "out of range"),
        (
            3,
            3,
            Text("1-1-2024"),
            "Plan!D4 (column \"Finish\"): task \"SL1\" finishes before it starts",
        ),
        (3, 6, Text("W1XX"), "Plan!G4 (column \"Predecessors\")"),
        (3, 6, Text("Q9"), "\"Q9\" is not the id of a task"),
        (2, 6, Text("H"), "cycle: W1 -> H -> W1"),
        (
            3,
            5,
            Text("Z"),
            "Plan!F4 (column \"Parent\"): \"Z\" is not the id of another task",
        ),
        (
            3,
            0,
            Text("W1"),
            "Plan!A4 (column \"Activity ID\"): task \"W1\" is also that of row 3",
        ),
        (2, 4, Date(JAN8 - 3.0), "Plan!E3"),
    ];
    for (i, (row, col, cell, wanted)) in cases.into_iter().enumerate() {
        let mut rows = plan();
        rows[row][col] = cell;
        if wanted.starts_with("Plan!E3") {
            // An actual finish without an actual start.
            rows[0][4] = Text("Actual Finish");
        }
        let path = workbook(dir.path(), &format!("bad{i}.xlsx"), "Plan", &rows);
        let e = read_schedule(&path, &Source::default())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(wanted) && e.contains(&format!("bad{i}.xlsx")),
            "{wanted:?} not in {e:?}"
        );
    }
    let e = read_schedule(
        &workbook(
            dir.path(),
            "headers.xlsx",
            "Plan",
            &[vec![Text("What"), Text("When")]],
        ),
        &Source::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("no id column") && e.contains("What, When"),
        "{e}"
    );
    let not_zip = dir.path().join("plan.xlsx");
    std::fs::write(&not_zip, "Id,Start\n").unwrap();
    let e = read_schedule(&not_zip, &Source::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("not a readable .xlsx"), "{e}");
}
