//! Wavefront OBJ: `v` (with the optional `r g b` vertex colour extension),
//! `vn` and `f` (polygons fan-triangulated; `v`, `v/vt`, `v//vn`, `v/vt/vn`;
//! negative indices count back from the last vertex). Other statements
//! (groups, materials, texture coordinates, lines) are ignored.
//!
//! Written by hand rather than with `tobj` because errors must name the file
//! and line, and `tobj` reports only the kind of error.

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::Path;

use glam::Vec3;

use crate::geometry::Mesh;
use crate::{Error, Result};

pub fn read_mesh(path: &Path) -> Result<Mesh> {
    let text = crate::input::read_to_string(path)?;
    parse(&text, path)
}

/// Parses OBJ text; `path` names the source in errors.
pub fn parse(text: &str, path: &Path) -> Result<Mesh> {
    let mut positions: Vec<Vec3> = Vec::new();
    let mut colors: Vec<[f32; 4]> = Vec::new();
    let mut normals: Vec<Vec3> = Vec::new();
    // (position, normal) pairs become output vertices: one position can
    // carry different normals in different faces.
    let mut corners: HashMap<(u32, u32), u32> = HashMap::new();
    let mut out = Mesh::default();
    let mut out_normal_index: Vec<u32> = Vec::new();
    let mut all_corners_have_normals = true;

    for (line_index, line) in text.lines().enumerate() {
        let at = || format!("line {}", line_index + 1);
        let line = line.split('#').next().unwrap_or("");
        let mut words = line.split_whitespace();
        let Some(keyword) = words.next() else {
            continue;
        };
        match keyword {
            "v" => {
                let values = floats(words, path, &at)?;
                if values.len() < 3 {
                    return Err(Error::invalid(path, at(), "a vertex needs x y z"));
                }
                positions.push(Vec3::new(values[0], values[1], values[2]));
                if values.len() >= 6 {
                    colors.push([values[3], values[4], values[5], 1.0]);
                }
            }
            "vn" => {
                let values = floats(words, path, &at)?;
                if values.len() < 3 {
                    return Err(Error::invalid(path, at(), "a normal needs x y z"));
                }
                normals.push(Vec3::new(values[0], values[1], values[2]));
            }
            "f" => {
                let mut face = Vec::new();
                for word in words {
                    let mut fields = word.split('/');
                    let v = index(fields.next(), positions.len(), "vertex", path, &at)?
                        .ok_or_else(|| {
                            Error::invalid(
                                path,
                                at(),
                                format!("face corner {word:?} has no vertex index"),
                            )
                        })?;
                    let _texture = fields.next();
                    let n = index(fields.next(), normals.len(), "normal", path, &at)?;
                    all_corners_have_normals &= n.is_some();
                    let n = n.unwrap_or(u32::MAX);
                    let id = *corners.entry((v, n)).or_insert_with(|| {
                        out.positions.push(positions[v as usize]);
                        out_normal_index.push(n);
                        if let Some(c) = colors.get(v as usize) {
                            out.colors.push(*c);
                        }
                        out.positions.len() as u32 - 1
                    });
                    face.push(id);
                }
                if face.len() < 3 {
                    return Err(Error::invalid(
                        path,
                        at(),
                        "a face needs at least 3 corners",
                    ));
                }
                for k in 1..face.len() - 1 {
                    out.indices.extend([face[0], face[k], face[k + 1]]);
                }
            }
            _ => {}
        }
    }
    if all_corners_have_normals && !out.positions.is_empty() {
        out.normals = out_normal_index
            .iter()
            .map(|&n| normals[n as usize])
            .collect();
    }
    if !colors.is_empty() && colors.len() != positions.len() {
        // Colours on some vertices only: not a colour attribute.
        out.colors.clear();
    }
    if out.colors.len() != out.positions.len() {
        out.colors.clear();
    }
    Ok(out)
}

fn floats<'a>(
    words: impl Iterator<Item = &'a str>,
    path: &Path,
    at: &dyn Fn() -> String,
) -> Result<Vec<f32>> {
    words
        .map(|w| {
            let x: f32 = w
                .parse()
                .map_err(|_| Error::invalid(path, at(), format!("{w:?} is not a number")))?;
            if x.is_finite() {
                Ok(x)
            } else {
                Err(Error::invalid(
                    path,
                    at(),
                    format!("{w:?} is not a finite number"),
                ))
            }
        })
        .collect()
}

/// A 1-based (or negative, relative) OBJ index into a list of `len`
/// elements, as a 0-based index; `None` when the field is absent or empty.
fn index(
    field: Option<&str>,
    len: usize,
    what: &str,
    path: &Path,
    at: &dyn Fn() -> String,
) -> Result<Option<u32>> {
    let Some(field) = field.filter(|f| !f.is_empty()) else {
        return Ok(None);
    };
    let i: i64 = field.parse().map_err(|_| {
        Error::invalid(
            path,
            at(),
            format!("{what} index {field:?} is not an integer"),
        )
    })?;
    let resolved = if i > 0 { i - 1 } else { len as i64 + i };
    if i == 0 || resolved < 0 || resolved >= len as i64 {
        return Err(Error::invalid(
            path,
            at(),
            format!("{what} index {i} is out of range ({len} defined so far)"),
        ));
    }
    Ok(Some(resolved as u32))
}

/// Writes `mesh` as OBJ (positions, normals if any, 1-based faces).
pub fn write_mesh(mesh: &Mesh, path: &Path) -> Result<()> {
    std::fs::write(path, to_string(mesh)).map_err(|e| Error::io(path, e))
}

pub fn to_string(mesh: &Mesh) -> String {
    let mut s = String::with_capacity(mesh.positions.len() * 40 + mesh.indices.len() * 8);
    let with_colors = mesh.colors.len() == mesh.positions.len() && !mesh.colors.is_empty();
    for (i, p) in mesh.positions.iter().enumerate() {
        let _ = write!(s, "v {} {} {}", p.x, p.y, p.z);
        if with_colors {
            let c = mesh.colors[i];
            let _ = write!(s, " {} {} {}", c[0], c[1], c[2]);
        }
        s.push('\n');
    }
    let with_normals = mesh.normals.len() == mesh.positions.len() && !mesh.normals.is_empty();
    if with_normals {
        for n in &mesh.normals {
            let _ = writeln!(s, "vn {} {} {}", n.x, n.y, n.z);
        }
    }
    for t in mesh.indices.chunks_exact(3) {
        let [a, b, c] = [t[0] + 1, t[1] + 1, t[2] + 1];
        let _ = if with_normals {
            writeln!(s, "f {a}//{a} {b}//{b} {c}//{c}")
        } else {
            writeln!(s, "f {a} {b} {c}")
        };
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p() -> &'static Path {
        Path::new("test.obj")
    }

    #[test]
    fn quad_with_normals_and_negative_indices() {
        let text =
            "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nvt 0 0\nf -4/1/1 -3/1/1 -2/1/1 -1/1/1\n";
        let m = parse(text, p()).unwrap();
        assert_eq!(m.indices, vec![0, 1, 2, 0, 2, 3]);
        assert_eq!(m.normals, vec![Vec3::Z; 4]);
        m.validate().unwrap();
    }

    #[test]
    fn one_position_with_two_normals_is_two_vertices() {
        let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nvn 0 0 1\nvn 1 0 0\nf 1//1 2//1 3//1\nf 1//2 3//2 4//2\n";
        let m = parse(text, p()).unwrap();
        assert_eq!(m.positions.len(), 6);
        assert_eq!(m.triangle_count(), 2);
    }

    #[test]
    fn errors_name_the_line() {
        let e = parse("v 0 0 0\nv 1 0 0\nf 1 2 3\n", p())
            .unwrap_err()
            .to_string();
        assert!(e.contains("test.obj") && e.contains("line 3"), "{e}");
        let e = parse("v 0 nan 0\n", p()).unwrap_err().to_string();
        assert!(e.contains("line 1") && e.contains("finite"), "{e}");
        let e = parse("v 0 0 0\nv 1 0 0\nf 1 2\n", p())
            .unwrap_err()
            .to_string();
        assert!(e.contains("at least 3"), "{e}");
    }

    #[test]
    fn written_mesh_reads_back() {
        let text = "v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nf 1 2 3\n";
        let m = parse(text, p()).unwrap();
        assert_eq!(m.colors.len(), 3);
        let back = parse(&to_string(&m), p()).unwrap();
        assert_eq!(back, m);
    }
}
