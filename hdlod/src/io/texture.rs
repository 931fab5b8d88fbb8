//! A mesh's colour texture as cluster GLBs carry it: texture coordinates
//! per vertex (`TEXCOORD_0`) and one PNG image (`baseColorTexture`, PNG
//! specification, W3C 2003), which `COLOR_0` multiplies. The builder's
//! baked colour (`geometry::bake`) is written this way.

use glam::Vec2;

use crate::geometry::Mesh;
use crate::geometry::bake::{self, Atlas, Baked};

/// A texture over a mesh: one coordinate per vertex, `(0, 0)` the image's
/// top left, and the image as PNG bytes.
#[derive(Debug, Clone, PartialEq)]
pub struct Texture {
    pub uvs: Vec<Vec2>,
    pub png: Vec<u8>,
}

/// The mesh as drawn with its baked colour and the texture that colours
/// it (`bake::drawn`).
pub fn textured(mesh: &Mesh, baked: &Baked) -> (Mesh, Texture) {
    let (drawn, uvs) = bake::drawn(mesh, baked);
    (
        drawn,
        Texture {
            uvs,
            png: encode_png(&baked.atlas),
        },
    )
}

impl Texture {
    /// Whether some texel is not opaque: a baked chart that its part does
    /// not cover holds its cover as alpha (`geometry::bake`), and its
    /// material is then blended.
    pub fn translucent(&self) -> bool {
        decode_png(&self.png).is_ok_and(|a| a.texels.iter().any(|t| t[3] < 255))
    }
}

/// The atlas as an RGBA PNG marked sRGB. Deterministic: the GLB's bytes,
/// and so its name, depend on the texels alone.
pub fn encode_png(atlas: &Atlas) -> Vec<u8> {
    let mut out = Vec::new();
    let mut encoder = png::Encoder::new(&mut out, atlas.width, atlas.height);
    encoder.set_color(png::ColorType::Rgba);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
    encoder.set_compression(png::Compression::Balanced);
    let mut writer = encoder
        .write_header()
        .expect("writing a PNG header to a Vec cannot fail");
    writer
        .write_image_data(bytemuck::cast_slice(&atlas.texels))
        .expect("the texels fill the image");
    writer.finish().expect("writing a PNG to a Vec cannot fail");
    out
}

/// A PNG as RGBA texels (grey, palette and 16-bit images converted).
pub fn decode_png(bytes: &[u8]) -> Result<Atlas, String> {
    let mut decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    decoder.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
    let mut reader = decoder
        .read_info()
        .map_err(|e| format!("not a readable PNG: {e}"))?;
    let size = reader
        .output_buffer_size()
        .ok_or("the PNG is too large to decode")?;
    let mut buffer = vec![0; size];
    let info = reader
        .next_frame(&mut buffer)
        .map_err(|e| format!("not a readable PNG: {e}"))?;
    let pixels = (info.width * info.height) as usize;
    let texels: Vec<[u8; 4]> = match info.color_type {
        png::ColorType::Rgba => buffer
            .chunks_exact(4)
            .map(|c| [c[0], c[1], c[2], c[3]])
            .collect(),
        png::ColorType::Rgb => buffer
            .chunks_exact(3)
            .map(|c| [c[0], c[1], c[2], 255])
            .collect(),
        png::ColorType::GrayscaleAlpha => buffer
            .chunks_exact(2)
            .map(|c| [c[0], c[0], c[0], c[1]])
            .collect(),
        png::ColorType::Grayscale => buffer.iter().map(|&g| [g, g, g, 255]).collect(),
        png::ColorType::Indexed => return Err("an indexed PNG was not expanded".into()),
    };
    if texels.len() < pixels {
        return Err(format!(
            "{} texels for a {}x{} PNG",
            texels.len(),
            info.width,
            info.height
        ));
    }
    Ok(Atlas {
        width: info.width,
        height: info.height,
        texels: texels[..pixels].to_vec(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn atlases_survive_png() {
        let atlas = Atlas {
            width: 3,
            height: 2,
            texels: vec![
                [255, 0, 0, 255],
                [0, 255, 0, 255],
                [0, 0, 255, 255],
                [1, 2, 3, 4],
                [200, 100, 50, 255],
                [9, 9, 9, 0],
            ],
        };
        let png = encode_png(&atlas);
        assert_eq!(&png[1..4], b"PNG");
        assert_eq!(decode_png(&png).unwrap(), atlas);
        assert_eq!(encode_png(&atlas), png);
        assert!(decode_png(b"not a png").is_err());
    }
}
