//! Primavera P6 XML (PMXML): fixtures/schedules/tiny-p6.xml is tiny.xer's
//! schedule as P6 XML, and reads the same; bad input names the object and
//! the field.
#![cfg(feature = "ifc")]

use std::path::{Path, PathBuf};

use hdlod::import::{Source, pmxml, read_schedule, xer};

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/schedules")
}

fn fixture() -> PathBuf {
    fixtures().join("tiny-p6.xml")
}

#[test]
fn p6_xml_reads_as_its_xer() {
    let xml = pmxml::read(&fixture(), Some("TINY")).unwrap();
    let xer = xer::read(&fixtures().join("tiny.xer"), Some("TINY")).unwrap();
    assert_eq!(xml, xer);
    // By ObjectId; the other layout (activities beside their project);
    // its link from TINY's activity is left out.
    let other = pmxml::read(&fixture(), Some("102")).unwrap();
    assert_eq!(other.len(), 1);
    assert_eq!(
        (other[0].id.as_str(), other[0].predecessors.len()),
        ("B1000", 0)
    );
    // Through the schedule readers: .xml by its root element.
    let source = Source {
        project: Some("TINY".into()),
        ..Source::default()
    };
    assert_eq!(read_schedule(&fixture(), &source).unwrap(), xer);
    let e = read_schedule(&fixture(), &Source::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("2 projects")
            && e.contains("--project")
            && e.contains("TINY (ObjectId 101, 4 activities)")
            && e.contains("OTHER (ObjectId 102, 1 activities)"),
        "{e}"
    );
}

#[test]
fn malformed_p6_xml_names_the_object_and_field() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(fixture()).unwrap();
    let cases = [
        (
            (
                "<PlannedStartDate>2024-03-04T08:00:00",
                "<PlannedStartDate>1850-03-04T08:00:00",
            ),
            &["Project[0]/Activity[2]/PlannedStartDate", "out of range"][..],
        ),
        (
            (
                "<PlannedFinishDate>2024-01-12T17:00:00",
                "<PlannedFinishDate>next friday",
            ),
            &["Project[0]/Activity[0]/PlannedFinishDate", "next friday"],
        ),
        (
            (
                "<Type>Start to Start</Type>",
                "<Type>Start to Middle</Type>",
            ),
            &["Project[0]/Relationship[1]/Type", "Start to Middle"],
        ),
        (
            (
                "<PredecessorActivityObjectId>1</PredecessorActivityObjectId><SuccessorActivityObjectId>2",
                "<PredecessorActivityObjectId>4</PredecessorActivityObjectId><SuccessorActivityObjectId>2",
            ),
            &["Relationship", "cycle", "A1010 -> A1020 -> M9000 -> A1010"],
        ),
        (
            (
                "<ValueObjectId>501</ValueObjectId>",
                "<ValueObjectId>599</ValueObjectId>",
            ),
            &["Project[0]/Activity[1]/Code[0]/ValueObjectId", "\"599\""],
        ),
        (
            ("<Id>A1020</Id>", ""),
            &["Project[0]/Activity[2]/Id", "without an Activity ID"],
        ),
        (
            ("<ActualStartDate>2024-01-09T08:00:00</ActualStartDate>", ""),
            &[
                "Project[0]/Activity[0]/ActualFinishDate",
                "needs an actual start",
            ],
        ),
        (
            (
                "<ParentObjectId>1001</ParentObjectId>",
                "<ParentObjectId>1002</ParentObjectId>",
            ),
            &["WBS 1002/ParentObjectId", "cycle"],
        ),
    ];
    for (i, ((from, to), wanted)) in cases.into_iter().enumerate() {
        assert!(text.contains(from), "{from}");
        let path = dir.path().join(format!("bad{i}.xml"));
        std::fs::write(&path, text.replacen(from, to, 1)).unwrap();
        let e = pmxml::read(&path, Some("TINY")).unwrap_err().to_string();
        for w in wanted {
            assert!(
                e.contains(w) && e.contains(&format!("bad{i}.xml")),
                "{w:?} not in {e:?}"
            );
        }
    }
}
