//! Stanford PLY, ascii and binary (little and big endian): the `vertex`
//! element's `x y z`, optional `nx ny nz` and `red green blue [alpha]`
//! (integers scaled from 0..255, floats taken as they are), and the `face`
//! element's `vertex_indices` (or `vertex_index`) list, polygons
//! fan-triangulated. Other elements and properties are read and skipped.
//!
//! Written by hand: the `ply-rs` crate is unmaintained, and errors here must
//! name the file and the element (`vertex 12`, `face 3`) at fault.

use std::path::Path;

use glam::Vec3;

use crate::geometry::Mesh;
use crate::{Error, Result};

pub fn read_mesh(path: &Path) -> Result<Mesh> {
    let bytes = crate::input::read(path)?;
    parse(&bytes, path)
}

#[derive(Clone, Copy, PartialEq)]
enum Format {
    Ascii,
    Little,
    Big,
}

#[derive(Clone, Copy)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(name: &str) -> Option<Scalar> {
        Some(match name {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    fn is_integer(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }
}

struct Property {
    name: String,
    /// `Some(count type)` for a list.
    list: Option<Scalar>,
    ty: Scalar,
}

struct Element {
    name: String,
    count: usize,
    properties: Vec<Property>,
}

/// The body of the file, read value by value.
struct Body<'a> {
    format: Format,
    data: &'a [u8],
    pos: usize,
}

impl Body<'_> {
    fn value(&mut self, ty: Scalar) -> Option<f64> {
        if self.format == Format::Ascii {
            while self.data.get(self.pos)?.is_ascii_whitespace() {
                self.pos += 1;
            }
            let start = self.pos;
            while self
                .data
                .get(self.pos)
                .is_some_and(|b| !b.is_ascii_whitespace())
            {
                self.pos += 1;
            }
            let word = std::str::from_utf8(&self.data[start..self.pos]).ok()?;
            return word.parse().ok();
        }
        let n = ty.size();
        let bytes = self.data.get(self.pos..self.pos + n)?;
        self.pos += n;
        let mut b = [0u8; 8];
        b[..n].copy_from_slice(bytes);
        if self.format == Format::Big {
            b[..n].reverse();
        }
        Some(match ty {
            Scalar::I8 => f64::from(b[0] as i8),
            Scalar::U8 => f64::from(b[0]),
            Scalar::I16 => f64::from(i16::from_le_bytes([b[0], b[1]])),
            Scalar::U16 => f64::from(u16::from_le_bytes([b[0], b[1]])),
            Scalar::I32 => f64::from(i32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            Scalar::U32 => f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            Scalar::F32 => f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            Scalar::F64 => f64::from_le_bytes(b),
        })
    }
}

pub fn parse(bytes: &[u8], path: &Path) -> Result<Mesh> {
    let (format, elements, body_start) = header(bytes, path)?;
    let mut body = Body {
        format,
        data: &bytes[body_start..],
        pos: 0,
    };
    let mut mesh = Mesh::default();
    let mut vertex_count = None;
    for element in &elements {
        let col = |name: &str| element.properties.iter().position(|p| p.name == name);
        let xyz = [col("x"), col("y"), col("z")];
        let normal = [col("nx"), col("ny"), col("nz")];
        let rgb = [col("red"), col("green"), col("blue"), col("alpha")];
        let faces = col("vertex_indices").or_else(|| col("vertex_index"));
        let is_vertex = element.name == "vertex";
        if is_vertex && xyz.iter().any(Option::is_none) {
            return Err(Error::invalid(
                path,
                "element vertex",
                "needs properties x, y and z",
            ));
        }
        let has_normals = is_vertex && normal.iter().all(Option::is_some);
        let has_colors = is_vertex && rgb[..3].iter().all(Option::is_some);
        let is_face = element.name == "face" && faces.is_some();
        if element.name == "face" && !is_face {
            return Err(Error::invalid(
                path,
                "element face",
                "has no vertex_indices list",
            ));
        }
        if is_vertex {
            vertex_count = Some(element.count);
            mesh.positions.reserve(element.count);
        }
        let mut row = vec![0.0f64; element.properties.len()];
        let mut list = Vec::new();
        for item in 0..element.count {
            let at = || format!("{} {item}", element.name);
            for (k, p) in element.properties.iter().enumerate() {
                let truncated = || {
                    Error::invalid(
                        path,
                        at(),
                        format!("property {} is missing or not a number", p.name),
                    )
                };
                if let Some(count_type) = p.list {
                    let n = body.value(count_type).ok_or_else(truncated)?;
                    if n < 0.0 || n.fract() != 0.0 {
                        return Err(Error::invalid(
                            path,
                            at(),
                            format!("list {} has a bad length {n}", p.name),
                        ));
                    }
                    let keep = is_face && Some(k) == faces;
                    list.clear();
                    for _ in 0..n as usize {
                        let v = body.value(p.ty).ok_or_else(truncated)?;
                        if keep {
                            list.push(v);
                        }
                    }
                } else {
                    row[k] = body.value(p.ty).ok_or_else(truncated)?;
                }
            }
            if is_vertex {
                let get = |c: Option<usize>| row[c.unwrap_or(0)] as f32;
                let p = Vec3::new(get(xyz[0]), get(xyz[1]), get(xyz[2]));
                if !p.is_finite() {
                    return Err(Error::invalid(
                        path,
                        at(),
                        format!("non-finite position {p}"),
                    ));
                }
                mesh.positions.push(p);
                if has_normals {
                    mesh.normals
                        .push(Vec3::new(get(normal[0]), get(normal[1]), get(normal[2])));
                }
                if has_colors {
                    let channel = |c: Option<usize>| match c {
                        None => 1.0,
                        Some(c) if element.properties[c].ty.is_integer() => row[c] as f32 / 255.0,
                        Some(c) => row[c] as f32,
                    };
                    mesh.colors.push([
                        channel(rgb[0]),
                        channel(rgb[1]),
                        channel(rgb[2]),
                        channel(rgb[3]),
                    ]);
                }
            } else if is_face {
                let Some(vertices) = vertex_count else {
                    return Err(Error::invalid(
                        path,
                        at(),
                        "faces come before the vertex element",
                    ));
                };
                if list.len() < 3 {
                    return Err(Error::invalid(
                        path,
                        at(),
                        "a face needs at least 3 vertices",
                    ));
                }
                if let Some(bad) = list
                    .iter()
                    .find(|&&v| v < 0.0 || v >= vertices as f64 || v.fract() != 0.0)
                {
                    return Err(Error::invalid(
                        path,
                        at(),
                        format!("vertex index {bad} is out of range ({vertices} vertices)"),
                    ));
                }
                for k in 1..list.len() - 1 {
                    mesh.indices
                        .extend([list[0] as u32, list[k] as u32, list[k + 1] as u32]);
                }
            }
        }
    }
    if vertex_count.is_none() {
        return Err(Error::invalid(path, "header", "no vertex element"));
    }
    Ok(mesh)
}

fn header(bytes: &[u8], path: &Path) -> Result<(Format, Vec<Element>, usize)> {
    let invalid =
        |line: usize, message: String| Error::invalid(path, format!("header line {line}"), message);
    let mut pos = 0;
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    for line_number in 1.. {
        let Some(len) = bytes[pos..].iter().position(|&b| b == b'\n') else {
            return Err(invalid(line_number, "the header has no end_header".into()));
        };
        let line = String::from_utf8_lossy(&bytes[pos..pos + len]);
        pos += len + 1;
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["ply"] if line_number == 1 => {}
            _ if line_number == 1 => {
                return Err(invalid(1, "not a PLY file (no \"ply\" magic)".into()));
            }
            ["format", f, _version] => {
                format = Some(match *f {
                    "ascii" => Format::Ascii,
                    "binary_little_endian" => Format::Little,
                    "binary_big_endian" => Format::Big,
                    _ => return Err(invalid(line_number, format!("unknown format {f:?}"))),
                });
            }
            ["comment", ..] | ["obj_info", ..] | [] => {}
            ["element", name, count] => elements.push(Element {
                name: name.to_string(),
                count: count.parse().map_err(|_| {
                    invalid(
                        line_number,
                        format!("element count {count:?} is not a number"),
                    )
                })?,
                properties: Vec::new(),
            }),
            ["property", rest @ ..] => {
                let Some(element) = elements.last_mut() else {
                    return Err(invalid(line_number, "a property before any element".into()));
                };
                let scalar = |s: &str| {
                    Scalar::parse(s)
                        .ok_or_else(|| invalid(line_number, format!("unknown property type {s:?}")))
                };
                element.properties.push(match rest {
                    ["list", count, ty, name] => Property {
                        name: name.to_string(),
                        list: Some(scalar(count)?),
                        ty: scalar(ty)?,
                    },
                    [ty, name] => Property {
                        name: name.to_string(),
                        list: None,
                        ty: scalar(ty)?,
                    },
                    _ => return Err(invalid(line_number, format!("bad property line {line:?}"))),
                });
            }
            ["end_header"] => break,
            _ => {
                return Err(invalid(
                    line_number,
                    format!("unexpected header line {line:?}"),
                ));
            }
        }
    }
    let format = format.ok_or_else(|| Error::invalid(path, "header", "no format line"))?;
    Ok((format, elements, pos))
}

#[cfg(test)]
mod tests {
    use super::*;

    const HEADER: &str = "element vertex 4\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";

    fn binary(big: bool) -> Vec<u8> {
        let f = if big {
            "binary_big_endian"
        } else {
            "binary_little_endian"
        };
        let mut b = format!("ply\nformat {f} 1.0\ncomment made by hand\n{HEADER}").into_bytes();
        for (x, y) in [(0.0f32, 0.0f32), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)] {
            for v in [x, y, 0.0] {
                b.extend(if big {
                    v.to_be_bytes()
                } else {
                    v.to_le_bytes()
                });
            }
            b.extend([255u8, 0, 51]);
        }
        b.push(4);
        for i in [0i32, 1, 2, 3] {
            b.extend(if big {
                i.to_be_bytes()
            } else {
                i.to_le_bytes()
            });
        }
        b
    }

    #[test]
    fn ascii_and_binary_agree() {
        let ascii = format!(
            "ply\nformat ascii 1.0\n{HEADER}0 0 0 255 0 51\n1 0 0 255 0 51\n1 1 0 255 0 51\n0 1 0 255 0 51\n4 0 1 2 3\n"
        );
        let a = parse(ascii.as_bytes(), Path::new("a.ply")).unwrap();
        assert_eq!(a.indices, vec![0, 1, 2, 0, 2, 3]);
        assert_eq!(a.colors[0], [1.0, 0.0, 0.2, 1.0]);
        assert_eq!(parse(&binary(false), Path::new("l.ply")).unwrap(), a);
        assert_eq!(parse(&binary(true), Path::new("b.ply")).unwrap(), a);
    }

    #[test]
    fn errors_name_the_element() {
        let mut b = binary(false);
        b.truncate(b.len() - 2);
        let e = parse(&b, Path::new("cut.ply")).unwrap_err().to_string();
        assert!(e.contains("cut.ply") && e.contains("face 0"), "{e}");
        let bad = format!(
            "ply\nformat ascii 1.0\n{HEADER}0 0 0 1 1 1\n1 0 0 1 1 1\n1 1 0 1 1 1\n0 1 0 1 1 1\n3 0 1 9\n"
        );
        let e = parse(bad.as_bytes(), Path::new("x.ply"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("face 0") && e.contains("out of range"), "{e}");
        let e = parse(b"solid stl\n", Path::new("x.ply"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("not a PLY"), "{e}");
    }
}
