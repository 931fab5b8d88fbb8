//! The IFC import against what IfcOpenShell reads of the same entities:
//! colours through boolean operands, type materials and the diffuse factor;
//! storeys through spaces; malformed geometry named element by element;
//! IFC4X3. Each case is a small hand-written file (every number below
//! follows from its text); the real Schependomlaan models when the test
//! data holds them.
#![cfg(feature = "ifc")]

mod common;

use std::path::{Path, PathBuf};

use hdlod::import::{Options, ifc, import};

/// Units, context and a site > building > storey "01 first floor" (#34,
/// placement #35) in millimetres; #40 is a 400 x 400 profile, #21 the
/// identity placement, #23 and #24 the z and x axes.
fn file(schema: &str, body: &str) -> String {
    format!(
        "ISO-10303-21;
HEADER;
FILE_DESCRIPTION(('ViewDefinition [ReferenceView]'),'2;1');
FILE_NAME('t.ifc','2024-01-01T00:00:00',('hdlod'),('hdlod'),'hand-written','hand-written','');
FILE_SCHEMA(('{schema}'));
ENDSEC;
DATA;
#1=IFCPROJECT('0YvctVUKr0kugbFTf53O9L',$,'P',$,$,$,$,(#20),#10);
#10=IFCUNITASSIGNMENT((#11,#12));
#11=IFCSIUNIT(*,.LENGTHUNIT.,.MILLI.,.METRE.);
#12=IFCSIUNIT(*,.PLANEANGLEUNIT.,$,.RADIAN.);
#20=IFCGEOMETRICREPRESENTATIONCONTEXT($,'Model',3,1.E-05,#21,$);
#21=IFCAXIS2PLACEMENT3D(#22,$,$);
#22=IFCCARTESIANPOINT((0.,0.,0.));
#23=IFCDIRECTION((0.,0.,1.));
#24=IFCDIRECTION((1.,0.,0.));
#30=IFCSITE('1SiteHdlodFidelity0001',$,'Site',$,$,#31,$,$,.ELEMENT.,$,$,$,$,$);
#31=IFCLOCALPLACEMENT($,#21);
#32=IFCBUILDING('1BldgHdlodFidelity0001',$,'Building',$,$,#33,$,$,.ELEMENT.,$,$,$);
#33=IFCLOCALPLACEMENT(#31,#21);
#34=IFCBUILDINGSTOREY('1StryHdlodFidelity0001',$,'01 first floor',$,$,#35,$,$,.ELEMENT.,0.);
#35=IFCLOCALPLACEMENT(#33,#21);
#36=IFCRELAGGREGATES('1AggHdlodFidelity00001',$,$,$,#1,(#30));
#37=IFCRELAGGREGATES('1AggHdlodFidelity00002',$,$,$,#30,(#32));
#38=IFCRELAGGREGATES('1AggHdlodFidelity00003',$,$,$,#32,(#34));
#40=IFCRECTANGLEPROFILEDEF(.AREA.,$,#41,400.,400.);
#41=IFCAXIS2PLACEMENT2D(#42,$);
#42=IFCCARTESIANPOINT((0.,0.));
{body}
ENDSEC;
END-ISO-10303-21;
"
    )
}

/// A column `#N` of the storey: 400 x 400 x 3000 mm at the storey's
/// origin, its body the extrusion `#N+4` (records #N to #N+4).
fn column(n: u32, guid: &str, name: &str) -> String {
    let [p, s, r, x] = [n + 1, n + 2, n + 3, n + 4];
    format!(
        "#{n}=IFCCOLUMN('{guid}',$,'{name}',$,$,#{p},#{s},$,.COLUMN.);
#{p}=IFCLOCALPLACEMENT(#35,#21);
#{s}=IFCPRODUCTDEFINITIONSHAPE($,$,(#{r}));
#{r}=IFCSHAPEREPRESENTATION(#20,'Body','SweptSolid',(#{x}));
#{x}=IFCEXTRUDEDAREASOLID(#40,#21,#23,3000.);"
    )
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

fn read(body: &str) -> ifc::Model {
    let dir = tempfile::tempdir().unwrap();
    ifc::read(&write(dir.path(), "t.ifc", &file("IFC4", body))).unwrap()
}

/// IFC colours are sRGB; the scene's are linear.
fn linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

fn element<'a>(model: &'a ifc::Model, name: &str) -> &'a ifc::Element {
    model
        .elements
        .iter()
        .find(|e| e.name == name)
        .unwrap_or_else(|| panic!("no element {name}: {:?}", model.skipped))
}

#[test]
fn a_boolean_result_without_a_style_shows_its_first_operands() {
    // The clipped solid is styled blue, the clippings (nested twice, as
    // Revit writes a column cut twice) are not; a second column's clipping
    // has a style of its own, red, which wins over its operand's blue.
    let model = read(&format!(
        "{}
#100=IFCSHAPEREPRESENTATION(#20,'Body','Clipping',(#110));
#102=IFCPRODUCTDEFINITIONSHAPE($,$,(#100));
#105=IFCPLANE(#106);
#106=IFCAXIS2PLACEMENT3D(#107,#23,#24);
#107=IFCCARTESIANPOINT((0.,0.,2500.));
#108=IFCHALFSPACESOLID(#105,.F.);
#109=IFCBOOLEANCLIPPINGRESULT(.DIFFERENCE.,#64,#108);
#110=IFCBOOLEANCLIPPINGRESULT(.DIFFERENCE.,#109,#108);
#111=IFCCOLOURRGB($,0.,0.,1.);
#112=IFCSURFACESTYLERENDERING(#111,0.,$,$,$,$,$,$,.NOTDEFINED.);
#113=IFCSURFACESTYLE('blue',.BOTH.,(#112));
#114=IFCSTYLEDITEM(#64,(#113),$);
{}
#120=IFCSHAPEREPRESENTATION(#20,'Body','Clipping',(#121));
#122=IFCPRODUCTDEFINITIONSHAPE($,$,(#120));
#121=IFCBOOLEANCLIPPINGRESULT(.DIFFERENCE.,#84,#108);
#123=IFCCOLOURRGB($,1.,0.,0.);
#124=IFCSURFACESTYLERENDERING(#123,0.,$,$,$,$,$,$,.NOTDEFINED.);
#125=IFCSURFACESTYLE('red',.BOTH.,(#124));
#126=IFCSTYLEDITEM(#121,(#125),$);
#127=IFCSTYLEDITEM(#84,(#113),$);
#190=IFCRELCONTAINEDINSPATIALSTRUCTURE('2ContHdlodFidelity0001',$,$,$,(#60,#80),#34);",
        column(60, "2ColHdlodFidelity00001", "clipped").replace("#62,$", "#102,$"),
        column(80, "2ColHdlodFidelity00002", "styled clipping").replace("#82,$", "#122,$"),
    ));
    let clipped = element(&model, "clipped");
    assert_eq!(clipped.color, [0.0, 0.0, 1.0, 1.0]);
    // Clipped at 2.5 m: the clipping, not the bare extrusion, was meshed.
    let (lo, hi) = clipped.mesh.bounds().unwrap();
    assert!(
        (hi.z - lo.z - 2.5).abs() < 1e-3,
        "height {} (the clipping was not meshed)",
        hi.z - lo.z
    );
    assert_eq!(
        element(&model, "styled clipping").color,
        [1.0, 0.0, 0.0, 1.0]
    );
}

/// A concrete column type (`#120`) whose material `#122` is styled green;
/// `material` replaces the material select associated with the type.
fn typed(material: &str) -> String {
    format!(
        "{}
{}
{}
#120=IFCCOLUMNTYPE('2TypHdlodFidelity00001',$,'C400',$,$,$,$,$,$,.COLUMN.);
#121=IFCRELDEFINESBYTYPE('2DbtHdlodFidelity00001',$,$,$,(#60,#70,#80),#120);
#122=IFCMATERIAL('concrete',$,$);
#123=IFCRELASSOCIATESMATERIAL('2RamHdlodFidelity00001',$,$,$,(#120),{material});
#124=IFCMATERIALDEFINITIONREPRESENTATION($,$,(#125),#122);
#125=IFCSTYLEDREPRESENTATION(#20,'Style','Material',(#126));
#126=IFCSTYLEDITEM($,(#127),$);
#127=IFCSURFACESTYLE('green',.BOTH.,(#128));
#128=IFCSURFACESTYLERENDERING(#129,0.,$,$,$,$,$,$,.NOTDEFINED.);
#129=IFCCOLOURRGB($,0.,1.,0.);
#130=IFCMATERIALLAYER(#122,400.,$,'core',$,$,$);
#131=IFCMATERIALLAYERSET((#130),'C400 layers',$);
#140=IFCMATERIAL('steel',$,$);
#141=IFCRELASSOCIATESMATERIAL('2RamHdlodFidelity00002',$,$,$,(#70),#140);
#142=IFCMATERIALDEFINITIONREPRESENTATION($,$,(#143),#140);
#143=IFCSTYLEDREPRESENTATION(#20,'Style','Material',(#144));
#144=IFCSTYLEDITEM($,(#145),$);
#145=IFCSURFACESTYLE('red',.BOTH.,(#146));
#146=IFCSURFACESTYLESHADING(#147,$);
#147=IFCCOLOURRGB($,1.,0.,0.);
#150=IFCSTYLEDITEM(#84,(#145),$);
#190=IFCRELCONTAINEDINSPATIALSTRUCTURE('2ContHdlodFidelity0001',$,$,$,(#60,#70,#80),#34);",
        column(60, "2ColHdlodFidelity00003", "typed"),
        column(70, "2ColHdlodFidelity00004", "own material"),
        column(80, "2ColHdlodFidelity00005", "styled item"),
    )
}

#[test]
fn an_element_without_a_material_takes_its_types() {
    for material in ["#122", "#131"] {
        let model = read(&typed(material));
        assert_eq!(
            element(&model, "typed").color,
            [0.0, 1.0, 0.0, 1.0],
            "type material {material}"
        );
        // The element's own material, then its item's style, come first.
        assert_eq!(element(&model, "own material").color, [1.0, 0.0, 0.0, 1.0]);
        assert_eq!(element(&model, "styled item").color, [1.0, 0.0, 0.0, 1.0]);
    }
}

#[test]
fn the_diffuse_factor_scales_the_surface_colour_and_a_diffuse_colour_replaces_it() {
    let model = read(&format!(
        "{}
{}
#105=IFCCOLOURRGB($,1.,0.5,0.);
#106=IFCSURFACESTYLERENDERING(#105,0.,IFCNORMALISEDRATIOMEASURE(0.5),$,$,$,$,$,.NOTDEFINED.);
#107=IFCSURFACESTYLE('orange at half',.BOTH.,(#106));
#108=IFCSTYLEDITEM(#64,(#107),$);
#115=IFCCOLOURRGB($,0.,0.,1.);
#116=IFCSURFACESTYLERENDERING(#105,0.4,#115,$,$,$,$,$,.NOTDEFINED.);
#117=IFCSURFACESTYLE('diffuse blue',.BOTH.,(#116));
#118=IFCSTYLEDITEM(#74,(#117),$);
#190=IFCRELCONTAINEDINSPATIALSTRUCTURE('2ContHdlodFidelity0001',$,$,$,(#60,#70),#34);",
        column(60, "2ColHdlodFidelity00006", "factor"),
        column(70, "2ColHdlodFidelity00007", "colour"),
    ));
    assert_eq!(
        element(&model, "factor").color,
        [linear(0.5), linear(0.25), 0.0, 1.0]
    );
    assert_eq!(element(&model, "colour").color, [0.0, 0.0, 1.0, 0.6]);
}

#[test]
fn elements_in_a_space_take_the_storey_the_space_belongs_to() {
    // A chair in the kitchen, a space of the storey; a lamp in an alcove, a
    // part of the kitchen; a bench contained in the building itself.
    let model = read(&format!(
        "{}
{}
{}
#110=IFCSPACE('2SpcHdlodFidelity00001',$,'kitchen',$,$,#35,$,$,.ELEMENT.,.INTERNAL.,$);
#111=IFCRELAGGREGATES('2AggHdlodFidelity00004',$,$,$,#34,(#110));
#112=IFCRELCONTAINEDINSPATIALSTRUCTURE('2ContHdlodFidelity0002',$,$,$,(#60),#110);
#120=IFCSPACE('2SpcHdlodFidelity00002',$,'alcove',$,$,#35,$,$,.PARTIAL.,.INTERNAL.,$);
#121=IFCRELAGGREGATES('2AggHdlodFidelity00005',$,$,$,#110,(#120));
#131=IFCRELCONTAINEDINSPATIALSTRUCTURE('2ContHdlodFidelity0003',$,$,$,(#70),#120);
#132=IFCRELCONTAINEDINSPATIALSTRUCTURE('2ContHdlodFidelity0004',$,$,$,(#80),#32);",
        column(60, "2ColHdlodFidelity00008", "chair"),
        column(70, "2ColHdlodFidelity00009", "lamp"),
        column(80, "2ColHdlodFidelity00010", "bench"),
    ));
    assert_eq!(
        element(&model, "chair").storey.as_deref(),
        Some("01 first floor")
    );
    assert_eq!(
        element(&model, "lamp").storey.as_deref(),
        Some("01 first floor")
    );
    assert_eq!(element(&model, "bench").storey, None);
}

/// Four elements whose geometry is broken, each in its own way.
fn broken() -> String {
    "#60=IFCWALL('2WalHdlodFidelity00001',$,'looping wall',$,$,#61,#62,$,.SOLIDWALL.);
#61=IFCLOCALPLACEMENT(#65,#21);
#65=IFCLOCALPLACEMENT(#61,#21);
#62=IFCPRODUCTDEFINITIONSHAPE($,$,(#63));
#63=IFCSHAPEREPRESENTATION(#20,'Body','SweptSolid',(#64));
#64=IFCEXTRUDEDAREASOLID(#40,#21,#23,3000.);
#70=IFCWALL('2WalHdlodFidelity00002',$,'wall without profile',$,$,#71,#72,$,.SOLIDWALL.);
#71=IFCLOCALPLACEMENT(#35,#21);
#72=IFCPRODUCTDEFINITIONSHAPE($,$,(#73));
#73=IFCSHAPEREPRESENTATION(#20,'Body','SweptSolid',(#74));
#74=IFCEXTRUDEDAREASOLID(#999,#21,#23,3000.);
#80=IFCSLAB('2SlbHdlodFidelity00001',$,'bad faces',$,$,#71,#82,$,.FLOOR.);
#82=IFCPRODUCTDEFINITIONSHAPE($,$,(#83));
#83=IFCSHAPEREPRESENTATION(#20,'Body','Tessellation',(#84));
#84=IFCPOLYGONALFACESET(#85,.T.,(#86,#87),$);
#85=IFCCARTESIANPOINTLIST3D(((0.,0.,0.),(1000.,0.,0.),(1000.,1000.,0.),(0.,1000.,0.)));
#86=IFCINDEXEDPOLYGONALFACE((1,2,3));
#87=IFCINDEXEDPOLYGONALFACE((1,3,9));
#90=IFCSLAB('2SlbHdlodFidelity00002',$,'bad triangles',$,$,#71,#92,$,.FLOOR.);
#92=IFCPRODUCTDEFINITIONSHAPE($,$,(#93));
#93=IFCSHAPEREPRESENTATION(#20,'Body','Tessellation',(#94));
#94=IFCTRIANGULATEDFACESET(#85,$,.T.,((1,2,3),(1,3,7)),$);
#190=IFCRELCONTAINEDINSPATIALSTRUCTURE('2ContHdlodFidelity0001',$,$,$,(#60,#70,#80,#90),#34);"
        .to_string()
}

#[test]
fn each_element_whose_geometry_fails_is_named_with_the_reason() {
    let dir = tempfile::tempdir().unwrap();
    let body = format!(
        "{}\n{}",
        broken(),
        column(100, "2ColHdlodFidelity00011", "good column")
    )
    .replace("(#60,#70,#80,#90)", "(#60,#70,#80,#90,#100)");
    let path = write(dir.path(), "broken.ifc", &file("IFC4", &body));
    let model = ifc::read(&path).unwrap();
    let names: Vec<&str> = model.elements.iter().map(|e| e.name.as_str()).collect();
    assert_eq!(names, ["good column"]);
    assert_eq!(model.warnings.len(), 4, "{:#?}", model.warnings);
    for (id, class, guid, reason) in [
        ("#60", "IfcWall", "2WalHdlodFidelity00001", "cyclic"),
        ("#70", "IfcWall", "2WalHdlodFidelity00002", "#999"),
        ("#80", "IfcSlab", "2SlbHdlodFidelity00001", "index 9"),
        ("#90", "IfcSlab", "2SlbHdlodFidelity00002", "index 7"),
    ] {
        let w = model
            .warnings
            .iter()
            .find(|w| w.contains(&format!("{id} ")))
            .unwrap_or_else(|| panic!("no warning for {id}: {:#?}", model.warnings));
        for part in ["broken.ifc", class, guid, reason] {
            assert!(w.contains(part), "{part} not in {w}");
        }
    }
    assert_eq!(
        model.skipped["IfcWall"].values().sum::<usize>()
            + model.skipped["IfcSlab"].values().sum::<usize>(),
        4,
        "{:?}",
        model.skipped
    );

    // Through the import: the warnings and the count are in the report.
    let (_, report) = import(&[path], &Options::default(), &|_| {}).unwrap();
    assert_eq!(report.elements, 1);
    assert_eq!(report.files[0].failed, 4);
    assert_eq!(
        report
            .warnings
            .iter()
            .filter(|w| w.contains("broken.ifc") && w.contains("geometry"))
            .count(),
        4,
        "{:#?}",
        report.warnings
    );
}

#[test]
fn a_file_none_of_whose_elements_import_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(dir.path(), "hopeless.ifc", &file("IFC4", &broken()));
    let e = ifc::read(&path).unwrap_err().to_string();
    assert!(
        e.contains("hopeless.ifc") && e.contains("none of its 4 elements"),
        "{e}"
    );
    // Naming the first failure, so that the cause is on the one line.
    assert!(
        e.contains("#60") && e.contains("2WalHdlodFidelity00001"),
        "{e}"
    );
}

#[test]
fn an_ifc4x3_file_imports() {
    // A storey with a wall beside a road with a pavement course: IFC4X3
    // facilities next to buildings.
    let dir = tempfile::tempdir().unwrap();
    let body = format!(
        "{}
#200=IFCROAD('3RoadHdlodFidelity0001',$,'road',$,$,#31,$,$,.ELEMENT.,$);
#201=IFCRELAGGREGATES('3AggHdlodFidelity00001',$,$,$,#30,(#200));
#210=IFCCOURSE('3CrsHdlodFidelity00001',$,'wearing course',$,$,#211,#212,$,.PAVEMENT.);
#211=IFCLOCALPLACEMENT(#31,#213);
#213=IFCAXIS2PLACEMENT3D(#214,$,$);
#214=IFCCARTESIANPOINT((10000.,0.,0.));
#212=IFCPRODUCTDEFINITIONSHAPE($,$,(#215));
#215=IFCSHAPEREPRESENTATION(#20,'Body','SweptSolid',(#216));
#216=IFCEXTRUDEDAREASOLID(#40,#21,#23,50.);
#220=IFCRELCONTAINEDINSPATIALSTRUCTURE('3ContHdlodFidelity0001',$,$,$,(#210),#200);
#190=IFCRELCONTAINEDINSPATIALSTRUCTURE('2ContHdlodFidelity0001',$,$,$,(#60),#34);",
        column(60, "2ColHdlodFidelity00012", "column")
    );
    let path = write(dir.path(), "road.ifc", &file("IFC4X3_ADD2", &body));
    let model = ifc::read(&path).unwrap();
    assert_eq!(model.schema, "IFC4X3_ADD2");
    let course = element(&model, "wearing course");
    assert_eq!(course.class, "IfcCourse");
    assert_eq!(course.storey, None);
    let (lo, hi) = course.mesh.bounds().unwrap();
    let (lo, hi) = (lo + course.origin.as_vec3(), hi + course.origin.as_vec3());
    assert!(
        (lo.x - 9.8).abs() < 1e-4 && (hi.z - 0.05).abs() < 1e-4,
        "{lo} {hi}"
    );
    assert_eq!(
        element(&model, "column").storey.as_deref(),
        Some("01 first floor")
    );
}

/// The display (sRGB) value of a linear channel.
fn srgb(c: f32) -> f32 {
    if c <= 0.0031308 {
        c * 12.92
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// Every style of the Schependomlaan models (ArchiCAD exports) gives its
/// `DiffuseColour` as a factor from 0.3 to 0.9 of the surface colour. The
/// colours below are IfcOpenShell 0.9.0's diffuse colours of these
/// elements (`scripts/ifc-compare`, which prints how many of each file
/// agree).
#[test]
fn schependomlaan_colours_are_ifcopenshells() {
    let Some(data) = common::data("schependomlaan") else {
        return;
    };
    let cases = [
        // The surveyor's marker, factor 0.51 of a light grey.
        (
            "ROOT-kalkzandsteen",
            "2sMqdqIU5BOBeQp_S3Hjru",
            [0.48, 0.48, 0.48],
        ),
        (
            "ROOT-kalkzandsteen",
            "0UEcPQQZf2ruz21iN4LQvo",
            [0.6194, 0.6245, 0.6092],
        ),
        (
            "ROOT-kalkzandsteen",
            "2jMXaMTy17tOYjMh68W7L1",
            [0.564, 0.5124, 0.2147],
        ),
        (
            "ROOT-staal",
            "3NdkzhQHz3wxMr0BA5Cn4d",
            [0.1196, 0.1294, 0.1608],
        ),
        (
            "ROOT-kapconstructie_dakkapellen_platdak",
            "0EHLW2CirCPANVPbmTwDe0",
            [0.3965, 0.1983, 0.0],
        ),
    ];
    let mut models = std::collections::HashMap::new();
    for (file, guid, theirs) in cases {
        let model = models.entry(file).or_insert_with(|| {
            ifc::read(&data.join("ifc").join(format!("{file}.ifczip"))).unwrap()
        });
        let e = model
            .elements
            .iter()
            .find(|e| e.id == guid)
            .unwrap_or_else(|| panic!("{file}: no {guid}"));
        assert!(e.styled && e.mesh.colors.is_empty(), "{file}: {guid}");
        let ours = [srgb(e.color[0]), srgb(e.color[1]), srgb(e.color[2])];
        assert!(
            ours.iter().zip(theirs).all(|(a, b)| (a - b).abs() < 2e-3),
            "{file}: {guid}: ours {ours:?}, IfcOpenShell's {theirs:?}"
        );
    }
}
