//! IFC work schedules: an IFC4 work schedule with nested tasks and
//! `IfcRelSequence` links (lags as `IfcLagTime` durations), and IFC2x3
//! tasks timed by `IfcScheduleTimeControl`; written here by hand, the
//! least that the schema asks of each entity.
#![cfg(feature = "ifc")]

use std::path::{Path, PathBuf};

use hdlod::import::{Source, read_schedule};
use hdlod::scene::LinkType;
use hdlod::time::parse_date;

fn step(dir: &Path, name: &str, schema: &str, data: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(
        &path,
        format!(
            "ISO-10303-21;\nHEADER;\nFILE_DESCRIPTION(('ViewDefinition [ReferenceView]'),'2;1');\n\
             FILE_NAME('{name}','2024-01-01T00:00:00',('hdlod'),('hdlod'),'hand-written','hand-written','');\n\
             FILE_SCHEMA(('{schema}'));\nENDSEC;\nDATA;\n{data}ENDSEC;\nEND-ISO-10303-21;\n"
        ),
    )
    .unwrap();
    path
}

/// A work plan's schedule: a summary task (no times of its own) over
/// walls and a slab, the slab starting 2 days after the walls finish, and
/// a roof (not in the schedule) with the slab, start to start.
const IFC4: &str = "\
#1=IFCWORKSCHEDULE('0WorkSchedHdlod0000001',$,'Shell schedule',$,$,'WS1','2024-01-01T00:00:00',$,$,$,$,'2024-01-08T08:00:00',$,.PLANNED.);
#10=IFCTASK('0TaskShellHdlod0000001',$,'Shell',$,$,'S',$,$,$,.F.,$,$,.CONSTRUCTION.);
#11=IFCTASK('0TaskWallsHdlod0000001',$,'Walls',$,$,'W',$,$,$,.F.,$,#21,.CONSTRUCTION.);
#12=IFCTASK('0TaskSlabHdlod00000001',$,'Slab',$,$,'SL',$,$,$,.F.,$,#22,.CONSTRUCTION.);
#13=IFCTASK('0TaskRoofHdlod00000001',$,'Roof',$,$,'R',$,$,$,.F.,$,#23,.CONSTRUCTION.);
#21=IFCTASKTIME($,$,$,$,$,'2024-01-08T08:00:00','2024-01-12T17:00:00','2024-01-08T08:00:00','2024-01-12T17:00:00','2024-01-10T08:00:00','2024-01-16T17:00:00',$,$,$,$,$,'2024-01-09T08:00:00',$,$,$);
#22=IFCTASKTIME($,$,$,$,$,'2024-01-15T08:00:00','2024-01-19T17:00:00',$,$,$,$,$,$,$,$,$,$,$,$,$);
#23=IFCTASKTIME($,$,$,$,$,'2024-01-15T08:00:00','2024-01-26T17:00:00',$,$,$,$,$,$,$,$,$,$,$,$,$);
#30=IFCRELNESTS('0NestHdlod000000000001',$,$,$,#10,(#11,#12));
#31=IFCRELASSIGNSTOCONTROL('0CtrlHdlod000000000001',$,$,$,(#10),$,#1);
#40=IFCLAGTIME($,$,$,IFCDURATION('P2DT0H'),.WORKTIME.);
#41=IFCRELSEQUENCE('0SeqHdlod0000000000001',$,$,$,#11,#12,#40,.FINISH_START.,$);
#42=IFCRELSEQUENCE('0SeqHdlod0000000000002',$,$,$,#12,#13,$,.START_START.,$);
";

#[test]
fn ifc4_work_schedules_with_links() {
    let dir = tempfile::tempdir().unwrap();
    let tasks = read_schedule(
        &step(dir.path(), "plan.ifc", "IFC4", IFC4),
        &Source::default(),
    )
    .unwrap();
    let got: Vec<(&str, Option<&str>, Option<&str>)> = tasks
        .iter()
        .map(|t| {
            (
                t.id.as_str(),
                t.parent.as_deref(),
                t.fields.get("work_schedule").map(String::as_str),
            )
        })
        .collect();
    // The roof is not in the schedule: not assigned, nor nested.
    assert_eq!(
        got,
        [
            ("S", None, Some("Shell schedule")),
            ("W", Some("S"), Some("Shell schedule")),
            ("SL", Some("S"), Some("Shell schedule")),
            ("R", None, None)
        ]
    );
    let d = |s: &str| parse_date(s).unwrap();
    let walls = &tasks[1];
    assert_eq!(walls.early.unwrap().1, d("2024-01-12T17:00:00"));
    assert_eq!(walls.late.unwrap().0, d("2024-01-10T08:00:00"));
    assert_eq!(walls.actual.start, Some(d("2024-01-09T08:00:00")));
    let link = |k: usize| {
        let p = &tasks[k].predecessors[0];
        (p.task.as_str(), p.kind, p.lag / 86400.0)
    };
    assert_eq!(link(2), ("W", LinkType::FinishStart, 2.0));
    assert_eq!(link(3), ("SL", LinkType::StartStart, 0.0));
    // The summary spans its tasks; its own early dates are none.
    assert_eq!(
        (tasks[0].start, tasks[0].finish),
        (d("2024-01-08T08:00:00"), d("2024-01-19T17:00:00"))
    );
    assert_eq!(tasks[0].early, None);

    // A cycle, and a lag that is no duration.
    let cycle = format!(
        "{IFC4}#43=IFCRELSEQUENCE('0SeqHdlod0000000000003',$,$,$,#13,#11,$,.FINISH_START.,$);\n"
    );
    let e = read_schedule(
        &step(dir.path(), "cycle.ifc", "IFC4", &cycle),
        &Source::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("cycle.ifc") && e.contains("IfcRelSequence") && e.contains("W -> SL -> R -> W"),
        "{e}"
    );
    let bad = IFC4.replace("IFCDURATION('P2DT0H')", "IFCDURATION('two days')");
    let e = read_schedule(
        &step(dir.path(), "lag.ifc", "IFC4", &bad),
        &Source::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("#40 (IfcLagTime) LagValue") && e.contains("two days"),
        "{e}"
    );
}

/// IFC2x3: times in an IfcScheduleTimeControl assigned with
/// IfcRelAssignsTasks; dates as IfcDateAndTime and bare IfcCalendarDate.
const IFC2X3: &str = "\
#1=IFCWORKSCHEDULE('0WorkSchedHdlod0000002',$,'Frame',$,$,'WS2',#50,$,$,$,$,#50,$,.PLANNED.,$);
#11=IFCTASK('0TaskColsHdlod00000001',$,'Columns',$,'CONSTRUCTION','C',$,$,.F.,$);
#12=IFCTASK('0TaskBeamHdlod00000001',$,'Beams',$,'CONSTRUCTION','B',$,$,.F.,$);
#20=IFCSCHEDULETIMECONTROL('0TimeHdlod000000000001',$,$,$,$,#53,$,$,#51,$,$,$,#52,$,$,$,$,$,$,$,$,$,$);
#21=IFCSCHEDULETIMECONTROL('0TimeHdlod000000000002',$,$,$,$,$,$,$,#54,$,$,$,#55,$,$,$,$,$,$,$,$,$,$);
#30=IFCRELASSIGNSTASKS('0AssiHdlod000000000001',$,$,$,(#11),$,#1,#20);
#31=IFCRELASSIGNSTASKS('0AssiHdlod000000000002',$,$,$,(#12),$,#1,#21);
#32=IFCRELSEQUENCE('0SeqHdlod0000000000009',$,$,$,#11,#12,28800.,.FINISH_START.);
#50=IFCCALENDARDATE(1,1,2024);
#51=IFCDATEANDTIME(#60,#61);
#52=IFCDATEANDTIME(#62,#63);
#53=IFCDATEANDTIME(#60,#64);
#54=IFCCALENDARDATE(15,1,2024);
#55=IFCCALENDARDATE(20,1,2024);
#60=IFCCALENDARDATE(8,1,2024);
#61=IFCLOCALTIME(8,0,0.,$,$);
#62=IFCCALENDARDATE(12,1,2024);
#63=IFCLOCALTIME(17,0,0.,$,$);
#64=IFCLOCALTIME(9,30,0.,$,$);
";

#[test]
fn ifc2x3_schedule_time_controls() {
    let dir = tempfile::tempdir().unwrap();
    let tasks = read_schedule(
        &step(dir.path(), "plan.ifc", "IFC2X3", IFC2X3),
        &Source::default(),
    )
    .unwrap();
    let d = |s: &str| parse_date(s).unwrap();
    let got: Vec<(&str, &str)> = tasks
        .iter()
        .map(|t| (t.id.as_str(), t.name.as_str()))
        .collect();
    assert_eq!(got, [("C", "Columns"), ("B", "Beams")]);
    let cols = &tasks[0];
    assert_eq!(
        (cols.start, cols.finish),
        (d("2024-01-08T08:00:00"), d("2024-01-12T17:00:00"))
    );
    assert_eq!(cols.actual.start, Some(d("2024-01-08T09:30:00")));
    // IFC2x3 names the type in ObjectType; the name is kept beside ours.
    let kind = cols.kind.unwrap();
    assert_eq!(kind.kind, hdlod::scene::TaskType::Construct);
    assert_eq!(kind.ifc, Some("CONSTRUCTION"));
    assert_eq!(cols.fields["work_schedule"], "Frame");
    // A bare calendar date is its midnight; the lag is seconds.
    assert_eq!(
        (tasks[1].start, tasks[1].finish),
        (d("2024-01-15"), d("2024-01-20"))
    );
    assert_eq!(tasks[1].predecessors[0].task, "C");
    assert_eq!(tasks[1].predecessors[0].lag, 28800.0);

    let bad = IFC2X3.replace("IFCCALENDARDATE(20,1,2024)", "IFCCALENDARDATE(32,1,2024)");
    let e = read_schedule(
        &step(dir.path(), "bad.ifc", "IFC2X3", &bad),
        &Source::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("#21 (IfcScheduleTimeControl) ScheduleFinish") && e.contains("2024-01-32"),
        "{e}"
    );
}
