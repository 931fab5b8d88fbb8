//! Baked colour: the colours of the detail a reduced cluster dropped,
//! kept as texels of a small texture per cluster, so that a box or a quad
//! keeps a facade's window bands without their triangles. After Cohen,
//! Olano and Manocha, "Appearance-preserving simplification", SIGGRAPH 1998
//! (colour stored in a texture map over the simplified surface, each
//! texel taken from the original surface it stands for), with the charts of
//! Sander, Snyder, Gortler and Hoppe, "Texture mapping progressive
//! meshes", SIGGRAPH 2001, reduced to their simplest form: one planar
//! chart per connected set of coplanar triangles of one object and vertex
//! colour, its bounding rectangle in the plane, shelf-packed (next-fit
//! decreasing height) into one atlas with a texel of gutter around each
//! chart.
//!
//! Only colour changes: positions, triangles and feature ids are the
//! reduced mesh's as they are, and so is every error bound measured on
//! them. A texel takes the colour the source surface shows in front of
//! it: the first source surface met along rays through it, from `reach`
//! in front of the chart to `reach` behind it, each from its own
//! direction within 45 degrees of the chart's normal (a wall kept as it
//! was takes the window bands the reduction dropped in front of it, and
//! a lattice before it as the eye sees it at a slant), else the nearest
//! point of the source. The source is the original objects where
//! the builder keeps them, else the children's geometry with their own
//! baked colour. A chart of one colour, that of its vertices, keeps its
//! vertex colours; one of another colour shrinks to one texel. Plain areas
//! are filled block by block (`Surface::fill`), so only colour borders
//! cost queries texel by texel: a few samples each, multi-jittered (Chiu,
//! Shirley and Wang 1994), so that thin bands along the chart's axes get
//! their share of the texel. A chart the source does not cover (a box
//! standing for a lattice) keeps, as each texel's alpha, how much of it
//! the source covers (`Surface::covers`), seen through the part from
//! directions over the hemisphere in front of it, cosine-weighted (Malley's
//! method; Pharr, Jakob and Humphreys, "Physically Based Rendering", on
//! cosine-weighted hemisphere sampling).

use rustc_hash::{FxHashMap, FxHashSet};

use glam::{DVec3, Vec2, Vec3, Vec3A};

use super::Mesh;
use super::closest::{TriangleSet, closest_point_on_triangle};

/// An RGBA image, 8 bits per channel, the colour channels sRGB-encoded
/// (as glTF's `baseColorTexture`), rows from the top (texture coordinate
/// `v = 0`).
#[derive(Debug, Clone, PartialEq)]
pub struct Atlas {
    pub width: u32,
    pub height: u32,
    pub texels: Vec<[u8; 4]>,
}

/// A mesh's baked colour: per triangle, its corners' texture coordinates
/// in the atlas, or `None` where the triangle keeps its vertex colours.
#[derive(Debug, Clone, PartialEq)]
pub struct Baked {
    pub corners: Vec<Option<[Vec2; 3]>>,
    pub atlas: Atlas,
}

/// A surface the texels are taken from: a mesh and its own baked colour.
#[derive(Debug, Clone, Copy)]
pub struct Source<'a> {
    pub mesh: &'a Mesh,
    pub baked: Option<&'a Baked>,
}

/// How fine the texture is.
#[derive(Debug, Clone, Copy)]
pub struct BakeOptions {
    /// The texel's side, scene units: the cluster's error, about a pixel
    /// where the cut draws it at its budget.
    pub texel: f32,
    /// How far in front of and behind a texel the source is looked for:
    /// the mesh's bound of its distance to the sources.
    pub reach: f32,
    /// The most texels along either side of the atlas; charts are baked
    /// coarser than `texel` when they would not fit.
    pub max_size: u32,
}

/// Texels of gutter around each chart, holding the source's colour past
/// its edge: bilinear filtering reads half a texel past it, and the first
/// mipmap level (which the viewer uses where a texel is under a pixel) a
/// texel of the full-size image more.
const GUTTER: u32 = 2;
/// The white block every untextured triangle samples (its vertex colour
/// times white): bilinear filtering at its centre reads white alone.
const WHITE: u32 = 4;
/// Texels within this of each other in every channel make a uniform chart.
const UNIFORM: u8 = 2;
/// Coarser texels by this factor while the charts do not fit the atlas.
const COARSER: f32 = 1.25;

/// Bakes the colour of `sources` into the triangles of `mesh`: each texel
/// the colour the source shows there seen from the front of its chart (the
/// first source surface met along the chart's normal from `reach` in front
/// of the texel to `reach` behind it), or, where that meets none, of the
/// source's nearest point; on a chart the source does not cover, alpha is
/// the share of the texel it covers. Charts of one colour that their
/// triangles' vertices already have keep their vertex colours. `None` when all do,
/// when the sources are empty, or when the charts cannot fit `max_size`
/// even at a texel each.
pub fn bake(mesh: &Mesh, sources: &[Source], options: &BakeOptions) -> Option<Baked> {
    if mesh.is_empty() {
        return None;
    }
    let surface = Surface::new(sources)?;
    let proxy = Proxy::new(mesh);
    let all: Vec<usize> = (0..mesh.triangle_count()).collect();
    let charts = charts(mesh, &all);
    let max = options.max_size.max(WHITE + 2 * GUTTER);
    let inner = (max - 2 * GUTTER) as f32;
    let longest = charts
        .iter()
        .map(|c| c.size.max_element())
        .fold(0.0, f32::max);
    let start = if options.texel > 0.0 && options.texel.is_finite() {
        options.texel
    } else {
        (longest / inner).max(f32::MIN_POSITIVE)
    };
    let reach = options.reach.max(0.0);
    // Each chart sampled at the texel, or coarser where it would not fit.
    let first: Vec<(f32, [u32; 2], Vec<[u8; 4]>)> = charts
        .iter()
        .map(|c| {
            let texel = start.max(c.size.max_element() / inner);
            let size = c.texels(texel);
            (texel, size, surface.sample(c, size, texel, reach, &proxy))
        })
        .collect();
    // Charts that need a texture: not one colour, or one other than their
    // vertices'; one colour shrinks to one texel.
    let mut wanted: Vec<(usize, bool)> = Vec::new();
    for (k, (_, size, texels)) in first.iter().enumerate() {
        let uniform = is_uniform(texels, *size);
        let centre = texels[(GUTTER * size[0] + GUTTER) as usize];
        let own = vertex_colour(mesh, &charts[k].triangles)
            .map(opaque)
            .map(encode);
        let plain =
            uniform && own.is_some_and(|c| (0..4).all(|i| c[i].abs_diff(centre[i]) <= UNIFORM));
        if !plain {
            wanted.push((k, uniform));
        }
    }
    if wanted.is_empty() {
        return None;
    }
    let least = (1 + 2 * GUTTER).pow(2) as u64;
    if wanted.len() as u64 * least + u64::from(WHITE * WHITE) > u64::from(max) * u64::from(max) {
        return None;
    }
    let mut texel = start;
    let (sizes, layout) = loop {
        let sizes: Vec<[u32; 2]> = wanted
            .iter()
            .map(|&(k, uniform)| {
                if uniform {
                    [1 + 2 * GUTTER; 2]
                } else {
                    charts[k].texels(texel)
                }
            })
            .collect();
        if let Some(layout) = pack(&sizes, max) {
            break (sizes, layout);
        }
        texel *= COARSER;
    };
    let texels: Vec<Vec<[u8; 4]>> = wanted
        .iter()
        .zip(&sizes)
        .map(|(&(k, uniform), &size)| {
            let (at, first_size, texels) = &first[k];
            if uniform {
                vec![
                    texels[(GUTTER * first_size[0] + GUTTER) as usize];
                    (size[0] * size[1]) as usize
                ]
            } else if *at == texel {
                texels.clone()
            } else {
                surface.sample(&charts[k], size, texel, reach, &proxy)
            }
        })
        .collect();
    let chosen: Vec<&Chart> = wanted.iter().map(|&(k, _)| &charts[k]).collect();
    Some(assemble(mesh, &chosen, &sizes, &layout, &texels, texel))
}

/// A vertex colour as a texel holds it: opaque, since a texel's alpha is
/// how much of it the source covers, and vertex colours are drawn opaque
/// whatever their alpha (a glass pane's colour is seen, not seen through).
fn opaque([r, g, b, _]: [f32; 4]) -> [f32; 4] {
    [r, g, b, 1.0]
}

/// The one colour of every vertex of `triangles`, if they have one.
fn vertex_colour(mesh: &Mesh, triangles: &[usize]) -> Option<[f32; 4]> {
    let colour = |i: u32| mesh.colors.get(i as usize).copied().unwrap_or([1.0; 4]);
    let first = colour(mesh.indices[triangles[0] * 3]);
    triangles
        .iter()
        .flat_map(|&t| &mesh.indices[t * 3..t * 3 + 3])
        .all(|&i| colour(i) == first)
        .then_some(first)
}

/// One chart: coplanar, edge-connected triangles of one feature and
/// vertex colour, and the
/// rectangle of their plane that holds them.
struct Chart {
    triangles: Vec<usize>,
    origin: Vec3,
    u: Vec3,
    v: Vec3,
    /// The rectangle's low corner in `(u, v)` and its size.
    low: Vec2,
    size: Vec2,
    /// Every corner was the same point (a degenerate triangle).
    point: bool,
    /// The plane's normal, the side the chart is seen from (`None` for a
    /// segment or a point).
    normal: Option<Vec3>,
    /// Points inside its triangles (at most [`PROBES`]), where a ray tells
    /// whether the source covers the chart ([`Surface::covers`]).
    probes: Vec<Vec3>,
}

impl Chart {
    /// Texels across and along, gutter excluded: at least one, and none
    /// larger than `texel`.
    fn cells(&self, texel: f32) -> [u32; 2] {
        let n = |x: f32| {
            if self.point {
                1
            } else {
                ((x / texel).ceil() as u32).max(1)
            }
        };
        [n(self.size.x), n(self.size.y)]
    }

    /// Texels across and along, gutter included.
    fn texels(&self, texel: f32) -> [u32; 2] {
        let [x, y] = self.cells(texel);
        [x + 2 * GUTTER, y + 2 * GUTTER]
    }

    /// The sides of the chart's texels, each at most `texel`: the chart's
    /// rectangle split into whole texels. A texel that ran past the
    /// rectangle's edge would average what lies beyond it into its colour
    /// and its cover: a face 1.5 m tall under texels of 2 m kept three
    /// quarters of its cover.
    fn step(&self, texel: f32) -> Vec2 {
        let [x, y] = self.cells(texel);
        let side = |size: f32, n: u32| {
            if size > 0.0 { size / n as f32 } else { texel }
        };
        Vec2::new(side(self.size.x, x), side(self.size.y, y))
    }

    /// Where a point of the plane falls, in texels from the chart's
    /// corner (gutter included).
    fn at(&self, p: Vec3, texel: f32) -> Vec2 {
        if self.point {
            return Vec2::splat(GUTTER as f32 + 0.5);
        }
        let d = p - self.origin;
        (Vec2::new(d.dot(self.u), d.dot(self.v)) - self.low) / self.step(texel)
            + Vec2::splat(GUTTER as f32)
    }

    /// The point of the plane at `(x, y)` texels from the chart's corner
    /// (gutter included): texel `(i, j)`'s centre is at `(i + 0.5, j + 0.5)`.
    fn point(&self, x: f32, y: f32, texel: f32) -> Vec3 {
        let step = self.step(texel);
        let x = self.low.x + (x - GUTTER as f32) * step.x;
        let y = self.low.y + (y - GUTTER as f32) * step.y;
        self.origin + self.u * x + self.v * y
    }
}

/// Triangles in one plane (normals within this, `1 - cos`)...
const COPLANAR_ANGLE: f32 = 1e-4;
/// ...and offsets within this share of the triangle's size.
const COPLANAR_OFFSET: f32 = 1e-4;

fn charts(mesh: &Mesh, todo: &[usize]) -> Vec<Chart> {
    let corners = |k: usize| {
        let t = &mesh.indices[k * 3..k * 3 + 3];
        [0, 1, 2].map(|c| mesh.positions[t[c] as usize])
    };
    let feature = |k: usize| mesh.features.get(mesh.indices[k * 3] as usize).copied();
    // A chart keeps to one vertex colour, so that a plain region kept as
    // it was is a plain chart, which keeps its vertex colour.
    let colour = |k: usize| vertex_colour(mesh, &[k]).map(|c| c.map(f32::to_bits));
    let normal = |k: usize| {
        let [a, b, c] = corners(k);
        (b - a).cross(c - a).try_normalize()
    };
    // Triangles by their edges (corner positions, either way round).
    let mut by_edge: FxHashMap<([u32; 3], [u32; 3]), Vec<usize>> = FxHashMap::default();
    let edge = |p: Vec3, q: Vec3| {
        let (a, b) = (
            p.to_array().map(f32::to_bits),
            q.to_array().map(f32::to_bits),
        );
        if a <= b { (a, b) } else { (b, a) }
    };
    for &k in todo {
        let [a, b, c] = corners(k);
        for (p, q) in [(a, b), (b, c), (c, a)] {
            by_edge.entry(edge(p, q)).or_default().push(k);
        }
    }
    let mut seen: FxHashSet<usize> =
        FxHashSet::with_capacity_and_hasher(todo.len(), Default::default());
    let mut out = Vec::new();
    for &seed in todo {
        if !seen.insert(seed) {
            continue;
        }
        let mut triangles = vec![seed];
        if let Some(n) = normal(seed) {
            let [a, b, c] = corners(seed);
            let scale = (b - a)
                .length()
                .max((c - a).length())
                .max(f32::MIN_POSITIVE);
            let mut stack = vec![seed];
            while let Some(k) = stack.pop() {
                let [p, q, r] = corners(k);
                for (x, y) in [(p, q), (q, r), (r, p)] {
                    for &m in &by_edge[&edge(x, y)] {
                        if seen.contains(&m)
                            || feature(m) != feature(seed)
                            || colour(m) != colour(seed)
                        {
                            continue;
                        }
                        let Some(nm) = normal(m) else { continue };
                        let flat = corners(m)
                            .iter()
                            .all(|p| n.dot(*p - a).abs() <= COPLANAR_OFFSET * scale);
                        if 1.0 - n.dot(nm) <= COPLANAR_ANGLE && flat {
                            seen.insert(m);
                            triangles.push(m);
                            stack.push(m);
                        }
                    }
                }
            }
        }
        out.push(chart(&triangles, &corners));
    }
    out
}

/// The chart of `triangles`, in the plane of the first: along the world's
/// axes when it faces along one (a box's faces, a quad), else along its
/// longest edge.
fn chart(triangles: &[usize], corners: &dyn Fn(usize) -> [Vec3; 3]) -> Chart {
    let [a, b, c] = corners(triangles[0]);
    let longest = [b - a, c - b, a - c]
        .into_iter()
        .max_by(|x, y| x.length_squared().total_cmp(&y.length_squared()))
        .unwrap_or(Vec3::X);
    let normal = (b - a).cross(c - a).try_normalize();
    let (u, v) = match normal {
        Some(n) => {
            let axis = n.abs().max_position();
            if n.abs()[axis] > 1.0 - COPLANAR_ANGLE {
                (Vec3::AXES[(axis + 1) % 3], Vec3::AXES[(axis + 2) % 3])
            } else {
                let u = longest.normalize();
                (u, n.cross(u))
            }
        }
        // A segment or a point: along it.
        None => {
            let u = longest.try_normalize().unwrap_or(Vec3::X);
            (u, u.any_orthonormal_vector())
        }
    };
    // Each triangle's centroid and the points halfway from it to each
    // corner, from triangles spread over the chart.
    let step = (4 * triangles.len()).div_ceil(PROBES).max(1);
    let probes = triangles
        .iter()
        .step_by(step.div_ceil(4).max(1))
        .flat_map(|&k| {
            let [a, b, c] = corners(k);
            let m = (a + b + c) / 3.0;
            [m, (m + a) / 2.0, (m + b) / 2.0, (m + c) / 2.0]
        })
        .take(PROBES)
        .collect();
    let mut lo = Vec2::splat(f32::INFINITY);
    let mut hi = Vec2::splat(f32::NEG_INFINITY);
    for &k in triangles {
        for p in corners(k) {
            let q = Vec2::new((p - a).dot(u), (p - a).dot(v));
            lo = lo.min(q);
            hi = hi.max(q);
        }
    }
    Chart {
        triangles: triangles.to_vec(),
        origin: a,
        u,
        v,
        low: lo,
        size: hi - lo,
        point: hi == lo,
        normal,
        probes,
    }
}

/// Shelf packing of rectangles `sizes` (and the white block first) into an
/// atlas at most `max` on a side: the tallest first, left to right, a new
/// shelf when a row is full. Answers the atlas size and each rectangle's
/// corner, or `None` when they do not fit.
fn pack(sizes: &[[u32; 2]], max: u32) -> Option<([u32; 2], Vec<[u32; 2]>)> {
    let white = [WHITE, WHITE];
    let area: u64 = sizes
        .iter()
        .chain([&white])
        .map(|s| u64::from(s[0]) * u64::from(s[1]))
        .sum();
    let widest = sizes.iter().map(|s| s[0]).max().unwrap_or(0).max(WHITE);
    if widest > max || sizes.iter().any(|s| s[1] > max) {
        return None;
    }
    let mut order: Vec<usize> = (0..sizes.len()).collect();
    order.sort_by_key(|&k| {
        (
            std::cmp::Reverse(sizes[k][1]),
            std::cmp::Reverse(sizes[k][0]),
            k,
        )
    });
    let square = ((area as f64 * 1.1).sqrt().ceil() as u32).clamp(widest, max);
    for width in [square, max] {
        let mut at = vec![[0u32; 2]; sizes.len()];
        // The white block opens the first shelf.
        let (mut x, mut y, mut shelf) = (WHITE, 0u32, WHITE);
        let mut fits = true;
        for &k in &order {
            let [w, h] = sizes[k];
            if x + w > width {
                y += shelf;
                x = 0;
                shelf = 0;
            }
            if y + h > max {
                fits = false;
                break;
            }
            at[k] = [x, y];
            x += w;
            shelf = shelf.max(h);
        }
        if fits {
            return Some(([width, (y + shelf).max(WHITE)], at));
        }
    }
    None
}

/// All texels of a chart's own rectangle (not its gutter) within
/// `UNIFORM` of the first.
fn is_uniform(texels: &[[u8; 4]], [w, h]: [u32; 2]) -> bool {
    let at = |i: u32, j: u32| texels[(j * w + i) as usize];
    let first = at(GUTTER, GUTTER);
    (GUTTER..h - GUTTER).all(|j| {
        (GUTTER..w - GUTTER).all(|i| {
            let t = at(i, j);
            (0..4).all(|c| t[c].abs_diff(first[c]) <= UNIFORM)
        })
    })
}

/// The atlas of the baked charts, and every triangle's corners in it.
fn assemble(
    mesh: &Mesh,
    charts: &[&Chart],
    sizes: &[[u32; 2]],
    ([width, height], at): &([u32; 2], Vec<[u32; 2]>),
    baked: &[Vec<[u8; 4]>],
    texel: f32,
) -> Baked {
    let mut texels = vec![[0u8, 0, 0, 255]; (*width * *height) as usize];
    for j in 0..WHITE {
        for i in 0..WHITE {
            texels[(j * width + i) as usize] = [255; 4];
        }
    }
    let scale = Vec2::new(*width as f32, *height as f32);
    let mut corners = vec![None; mesh.triangle_count()];
    for (k, chart) in charts.iter().enumerate() {
        let [w, h] = sizes[k];
        let [x0, y0] = at[k];
        for j in 0..h {
            let row = ((y0 + j) * width + x0) as usize;
            texels[row..row + w as usize]
                .copy_from_slice(&baked[k][(j * w) as usize..((j + 1) * w) as usize]);
        }
        let shrunk = w == 1 + 2 * GUTTER && h == 1 + 2 * GUTTER;
        let corner = Vec2::new(x0 as f32, y0 as f32);
        for &t in &chart.triangles {
            let tri = &mesh.indices[t * 3..t * 3 + 3];
            corners[t] = Some([0, 1, 2].map(|c| {
                let local = if shrunk {
                    Vec2::splat(GUTTER as f32 + 0.5)
                } else {
                    chart.at(mesh.positions[tri[c] as usize], texel)
                };
                (corner + local) / scale
            }));
        }
    }
    Baked {
        corners,
        atlas: Atlas {
            width: *width,
            height: *height,
            texels,
        },
    }
}

/// The sources' triangles for nearest-point queries, and what colours them.
struct Surface<'a> {
    set: TriangleSet,
    /// Per input triangle: its source and its index there.
    owners: Vec<(u32, u32)>,
    /// Per input triangle: its texel where it is one colour all over (its
    /// corners' colours alike, or its texture coordinates one point).
    flat: Vec<Option<[u8; 4]>>,
    sources: &'a [Source<'a>],
}

/// How a chart is sampled: its texel, how far in front and behind the
/// source is looked for, and its rows' length.
#[derive(Clone, Copy)]
struct Sampling<'a> {
    chart: &'a Chart,
    texel: f32,
    reach: f32,
    row: u32,
    proxy: &'a Proxy<'a>,
}

/// The mesh being baked, as rays see it: how deep the part a chart stands
/// for lies behind it. Its triangle set is built on first use, since only
/// a chart its source does not cover asks.
struct Proxy<'a> {
    mesh: &'a Mesh,
    set: std::cell::OnceCell<TriangleSet>,
}

impl<'a> Proxy<'a> {
    fn new(mesh: &'a Mesh) -> Self {
        Proxy {
            mesh,
            set: std::cell::OnceCell::new(),
        }
    }

    /// How far behind `p`, a point of a chart, the mesh's next surface is
    /// along `-d`: the far side of the part the chart stands for (a
    /// lattice mast's box: the opposite face).
    fn depth(&self, p: Vec3, d: Vec3, reach: f32) -> Option<f32> {
        let set = self
            .set
            .get_or_init(|| TriangleSet::new(self.mesh.triangles()));
        // Off the chart's own plane, which the ray would meet at once.
        let lift = reach * 1e-3;
        set.first_hit(p - d * lift, -d, f32::MAX)
            .map(|(_, along)| along + lift)
    }
}

/// The most points a chart is probed at for its cover.
const PROBES: usize = 64;

/// Blocks of at most this many texels are sampled texel by texel.
const LEAST_BLOCK: u32 = 2;
/// Samples along each side of a texel on a colour border (their mean is
/// the texel): `SUBSAMPLES` x `SUBSAMPLES` cells, one sample each, placed
/// so that no two share a row or a column of `SUBSAMPLES`^2
/// ([`sample_offset`]).
const SUBSAMPLES: u32 = 3;

/// Where sample `(a, b)` of a texel lies in its square (0 to 1 along each
/// side): multi-jittered sampling (Chiu, Shirley and Wang, "Multi-jittered
/// sampling", Graphics Gems IV, 1994) in its canonical arrangement, not
/// jittered since a bake must be reproducible. Each sample is in its own
/// cell of the `n` x `n` grid and in its own row and column of the
/// `n^2` x `n^2` one, so a band along either chart axis (a mullion or a
/// transom on a facade) thinner than a cell still meets its share of the
/// samples to within `1 / n^2` of the texel, where on a regular grid it
/// met a whole row of them or none.
fn sample_offset(a: u32, b: u32) -> (f32, f32) {
    let n = SUBSAMPLES as f32;
    (
        (a as f32 + (b as f32 + 0.5) / n) / n,
        (b as f32 + (a as f32 + 0.5) / n) / n,
    )
}

/// The direction sample `(a, b)` of a texel looks from, over the
/// hemisphere in front of a chart (axes `u`, `v`, normal `n`):
/// cosine-weighted (Malley's method: a point of the unit disk lifted onto
/// the hemisphere), which weighs each direction by the share of the screen
/// a face takes seen from it, so that the mean cover over the views is the
/// ink the eye sees. The points are the texel's multi-jittered pattern
/// ([`sample_offset`]) with its cells permuted, `(a, b)` to
/// `(a + b, a + 2 b)` modulo 3 (a bijection of the 3 x 3 cells), so that a
/// sample's place and its direction are not tied to each other. The disk
/// is scaled by `widest`, the sine of the widest angle to the normal
/// (1: the whole hemisphere).
fn seen_from(a: u32, b: u32, u: Vec3, v: Vec3, n: Vec3, widest: f32) -> Vec3 {
    let (x, y) = sample_offset((a + b) % SUBSAMPLES, (a + 2 * b) % SUBSAMPLES);
    let (r, phi) = (widest * x.sqrt(), std::f32::consts::TAU * y);
    u * (r * phi.cos()) + v * (r * phi.sin()) + n * (1.0 - r * r).sqrt()
}

/// The widest slant of a covered chart's colour samples: 45 degrees, so
/// that a ray spanning `reach` across the chart strays at most `reach`
/// along it. Over the whole hemisphere the grazing rays (up to four times
/// as long) took the colour of what stands before the wall metres away,
/// a crane's mast speckling a facade it is far from.
const COLOUR_SLANT: f32 = std::f32::consts::FRAC_1_SQRT_2;

impl<'a> Surface<'a> {
    fn new(sources: &'a [Source<'a>]) -> Option<Self> {
        let owners: Vec<(u32, u32)> = sources
            .iter()
            .enumerate()
            .flat_map(|(s, src)| (0..src.mesh.triangle_count() as u32).map(move |k| (s as u32, k)))
            .collect();
        let set = TriangleSet::new(sources.iter().flat_map(|s| s.mesh.triangles()));
        let flat = owners
            .iter()
            .map(|&(s, k)| {
                let source = &sources[s as usize];
                let t = &source.mesh.indices[k as usize * 3..k as usize * 3 + 3];
                match source.baked.map(|b| (b, b.corners[k as usize])) {
                    Some((b, Some(uv))) => (uv[0] == uv[1] && uv[0] == uv[2])
                        .then(|| encode(sample_bilinear(&b.atlas, uv[0]))),
                    _ => {
                        let colour = |c: usize| {
                            source
                                .mesh
                                .colors
                                .get(t[c] as usize)
                                .copied()
                                .unwrap_or([1.0; 4])
                        };
                        (colour(0) == colour(1) && colour(0) == colour(2))
                            .then(|| encode(opaque(colour(0))))
                    }
                }
            })
            .collect();
        (!set.is_empty()).then_some(Surface {
            set,
            owners,
            flat,
            sources,
        })
    }

    /// The texels of `chart`, `size` texels of side `texel`, row by row.
    fn sample(
        &self,
        chart: &Chart,
        [w, h]: [u32; 2],
        texel: f32,
        reach: f32,
        proxy: &Proxy,
    ) -> Vec<[u8; 4]> {
        let mut out = vec![[255; 4]; (w * h) as usize];
        let mut hint = None;
        let at = Sampling {
            chart,
            texel,
            reach,
            row: w,
            proxy,
        };
        if self.covers(&at) {
            self.fill(&at, [0, 0, w, h], &mut out, &mut hint);
        } else {
            for j in GUTTER..h - GUTTER {
                for i in GUTTER..w - GUTTER {
                    out[(j * w + i) as usize] = self.texel_coverage(&at, i, j, &mut hint);
                }
            }
            // The gutter repeats the chart's edge: past the edge of a box
            // that bounds its lattice there is nothing to cover, and a
            // transparent gutter would fade the edge texels' cover by
            // half where filtering reads across it.
            let inner = |k: u32, n: u32| k.clamp(GUTTER, n - GUTTER - 1);
            for j in 0..h {
                for i in 0..w {
                    out[(j * w + i) as usize] = out[(inner(j, h) * w + inner(i, w)) as usize];
                }
            }
        }
        out
    }

    /// Whether the source covers the chart: a ray along its normal through
    /// each of its probes meets the source within `reach` either side. A
    /// chart that stands for a lattice (a crane's mast or jib as a box) or
    /// overhangs its part does not, and its texels then hold how much of
    /// them the source covers as alpha ([`Self::texel_coverage`]), where a
    /// covered chart is opaque.
    fn covers(&self, at: &Sampling) -> bool {
        let Some(n) = at.chart.normal.filter(|_| at.reach > 0.0) else {
            return true;
        };
        at.chart.probes.iter().all(|&p| {
            self.set
                .first_hit(p + n * at.reach, -n, 2.0 * at.reach)
                .is_some()
        })
    }

    /// Texel `(i, j)` of a chart the source does not cover: as
    /// [`Self::texel_average`], with its alpha the share of its samples
    /// whose ray meets the source (times that source's own alpha), its
    /// colour the mean of what they meet. A texel no ray meets takes the
    /// colour of the source's nearest point, transparent, so that
    /// filtering across its edge blends towards the right colour.
    ///
    /// Each sample's ray comes from its own direction ([`seen_from`]) and
    /// goes on through the part to the mesh's far side: the cover is what
    /// the eye sees through the face from all round, not only straight on.
    /// A face's drawn share of a pixel shrinks as it turns away, but a
    /// round member inside the box does not, and the members behind each
    /// other straight on stand apart at a slant: seen along the normal
    /// alone, a crane's lattice kept about half the ink the eye sees of it.
    fn texel_coverage(&self, at: &Sampling, i: u32, j: u32, hint: &mut Option<u32>) -> [u8; 4] {
        let n = at.chart.normal.expect("a covered chart has a normal");
        let mut sum = [0.0f32; 3];
        let mut alpha = 0.0f32;
        for b in 0..SUBSAMPLES {
            for a in 0..SUBSAMPLES {
                let (x, y) = sample_offset(a, b);
                let p = at.chart.point(i as f32 + x, j as f32 + y, at.texel);
                let d = seen_from(a, b, at.chart.u, at.chart.v, n, 1.0);
                let behind = at
                    .proxy
                    .depth(p, d, at.reach)
                    .map_or(at.reach, |depth| depth.max(at.reach));
                if let Some((t, along)) =
                    self.set.first_hit(p + d * at.reach, -d, at.reach + behind)
                {
                    let c = self.colour_at(p + d * (at.reach - along), t);
                    for k in 0..3 {
                        sum[k] += c[k] * c[3];
                    }
                    alpha += c[3];
                }
            }
        }
        let samples = (SUBSAMPLES * SUBSAMPLES) as f32;
        let rgb = if alpha > 0.0 {
            sum.map(|s| s / alpha)
        } else {
            let centre = at.chart.point(i as f32 + 0.5, j as f32 + 0.5, at.texel);
            match self.set.nearest(centre, *hint) {
                Some(near) => {
                    *hint = Some(near.triangle);
                    let c = self.colour_at(centre, near.triangle);
                    [c[0], c[1], c[2]]
                }
                None => [1.0; 3],
            }
        };
        encode([rgb[0], rgb[1], rgb[2], alpha / samples])
    }

    /// Texel `(i, j)` of a chart on a colour border: the mean of the
    /// source's linear colour at `SUBSAMPLES` x `SUBSAMPLES` points over
    /// its square ([`sample_offset`]). One sample at its centre would give
    /// a band border as a staircase of whole texels, where the eye (and a
    /// multisampled render of full detail) sees the share of the texel
    /// each colour covers. Each sample looks from its own direction
    /// ([`seen_from`] within [`COLOUR_SLANT`]), as the cover of a chart the
    /// source does not cover does over the whole hemisphere: a lattice
    /// standing in front of a wall (a crane's mast on the tower's face)
    /// shows more of itself against the wall seen at a slant than straight
    /// on, its members apart in depth.
    fn texel_average(
        &self,
        at: &Sampling,
        i: u32,
        j: u32,
        hint: &mut Option<u32>,
    ) -> Option<[u8; 4]> {
        let mut sum = [0.0f32; 4];
        let mut n = 0u32;
        for b in 0..SUBSAMPLES {
            for a in 0..SUBSAMPLES {
                let (x, y) = sample_offset(a, b);
                let p = at.chart.point(i as f32 + x, j as f32 + y, at.texel);
                // The ray spans `reach` either side of the chart across
                // it, as straight on: a slanted one is longer.
                let (d, reach) = match at.chart.normal {
                    Some(n) => {
                        let d = seen_from(a, b, at.chart.u, at.chart.v, n, COLOUR_SLANT);
                        (Some(d), at.reach / d.dot(n))
                    }
                    None => (None, at.reach),
                };
                if let Some(c) = self.colour_seen(p, d, reach, hint) {
                    for (s, c) in sum.iter_mut().zip(c) {
                        *s += c;
                    }
                    n += 1;
                }
            }
        }
        (n > 0).then(|| encode(sum.map(|s| s / n as f32)))
    }

    /// The linear colour the source shows at `p` of a chart seen along
    /// `direction` (a unit vector out of the chart's front): the first
    /// surface met from `reach` in front of `p` to `reach` behind it, else
    /// the nearest.
    fn colour_seen(
        &self,
        p: Vec3,
        direction: Option<Vec3>,
        reach: f32,
        hint: &mut Option<u32>,
    ) -> Option<[f32; 4]> {
        if let Some(n) = direction.filter(|_| reach > 0.0)
            && let Some((t, along)) = self.set.first_hit(p + n * reach, -n, 2.0 * reach)
        {
            return Some(self.colour_at(p + n * (reach - along), t));
        }
        let n = self.set.nearest(p, *hint)?;
        *hint = Some(n.triangle);
        Some(self.colour_at(p, n.triangle))
    }

    /// Fills the block `[i, j, w, h]` of a chart's texels (rows `row`
    /// long). A block whose centre is `d` from the surface and whose
    /// texels' samples lie within `r` of its centre finds each of their
    /// nearest points within `d + 2 r` of the centre (the distance to a
    /// surface is 1-Lipschitz): when every triangle that near is of one
    /// colour, so is the block. Otherwise it is split in four, down to
    /// single texels, each the mean of its samples (`texel_average`).
    /// Large plain areas cost a few queries, and only colour borders are
    /// sampled texel by texel.
    fn fill(
        &self,
        at: &Sampling,
        [i0, j0, w, h]: [u32; 4],
        out: &mut [[u8; 4]],
        hint: &mut Option<u32>,
    ) {
        let Sampling {
            chart,
            texel,
            reach,
            row,
            ..
        } = *at;
        if w * h <= LEAST_BLOCK {
            for j in j0..j0 + h {
                for i in i0..i0 + w {
                    if let Some(c) = self.texel_average(at, i, j, hint) {
                        out[(j * row + i) as usize] = c;
                    }
                }
            }
            return;
        }
        let centre = chart.point(
            i0 as f32 + w as f32 / 2.0,
            j0 as f32 + h as f32 / 2.0,
            texel,
        );
        let Some(n) = self.set.nearest(centre, *hint) else {
            return;
        };
        *hint = Some(n.triangle);
        // The samples of its texels (`texel_average`) lie within this of
        // its centre: half the span of their centres, and the outermost
        // samples' offset from a centre, `(n^2 - 1) / (2 n^2)` of a texel
        // for `n` = `SUBSAMPLES` ([`sample_offset`]), on each side.
        let cells = (SUBSAMPLES * SUBSAMPLES) as f32;
        let spread = (cells - 1.0) / cells;
        let (sw, sh) = ((w - 1) as f32 + spread, (h - 1) as f32 + spread);
        let r = 0.5 * texel * (sw * sw + sh * sh).sqrt();
        // Nearest points lie within `d + 2 r` of the centre, surfaces met
        // in front or behind within `r + reach`; a little more for the
        // rounding of the distances.
        let reach = (n.distance_squared.sqrt() + 2.0 * r).max(r + reach) + 1e-3 * texel;
        let mut colour = None;
        let one = self.set.all_within(centre, reach, |t| {
            match (self.flat[self.set.input_index(t) as usize], colour) {
                (None, _) => false,
                (Some(c), None) => {
                    colour = Some(c);
                    true
                }
                (Some(c), Some(k)) => c == k,
            }
        });
        if let (true, Some(c)) = (one, colour) {
            for j in j0..j0 + h {
                out[(j * row + i0) as usize..(j * row + i0 + w) as usize].fill(c);
            }
            return;
        }
        let (wl, hl) = (w.div_ceil(2), h.div_ceil(2));
        for [i, j, bw, bh] in [
            [i0, j0, wl, hl],
            [i0 + wl, j0, w - wl, hl],
            [i0, j0 + hl, wl, h - hl],
            [i0 + wl, j0 + hl, w - wl, h - hl],
        ] {
            if bw > 0 && bh > 0 {
                self.fill(at, [i, j, bw, bh], out, hint);
            }
        }
    }

    /// The linear colour of the source at the point of `triangle` (a
    /// handle of the set) nearest to `p`.
    fn colour_at(&self, p: Vec3, triangle: u32) -> [f32; 4] {
        let [a, b, c] = self.set.corners(triangle);
        let q = closest_point_on_triangle(Vec3A::from(p), a.into(), b.into(), c.into());
        let w = barycentric(Vec3::from(q), a, b, c);
        let (s, k) = self.owners[self.set.input_index(triangle) as usize];
        let source = &self.sources[s as usize];
        let t = &source.mesh.indices[k as usize * 3..k as usize * 3 + 3];
        if let Some(uv) = source.baked.and_then(|b| b.corners[k as usize]) {
            let at = uv[0] * w[0] + uv[1] * w[1] + uv[2] * w[2];
            return sample_bilinear(&source.baked.expect("has corners").atlas, at);
        }
        let colour = |c: usize| {
            source
                .mesh
                .colors
                .get(t[c] as usize)
                .copied()
                .unwrap_or([1.0; 4])
        };
        let (ca, cb, cc) = (colour(0), colour(1), colour(2));
        opaque(std::array::from_fn(|i| {
            ca[i] * w[0] + cb[i] * w[1] + cc[i] * w[2]
        }))
    }
}

/// The barycentric weights of `q` (a point of the triangle) in `abc`, in
/// double precision; a degenerate triangle gives its nearest corner.
fn barycentric(q: Vec3, a: Vec3, b: Vec3, c: Vec3) -> [f32; 3] {
    let (q, a, b, c) = (q.as_dvec3(), a.as_dvec3(), b.as_dvec3(), c.as_dvec3());
    let (v0, v1, v2) = (b - a, c - a, q - a);
    let (d00, d01, d11) = (v0.dot(v0), v0.dot(v1), v1.dot(v1));
    let (d20, d21) = (v2.dot(v0), v2.dot(v1));
    let denom = d00 * d11 - d01 * d01;
    if denom.abs() <= f64::EPSILON * d00 * d11 || denom == 0.0 {
        let d = [a, b, c].map(|x: DVec3| x.distance_squared(q));
        let nearest = (0..3).min_by(|&i, &j| d[i].total_cmp(&d[j])).unwrap_or(0);
        let mut w = [0.0; 3];
        w[nearest] = 1.0;
        return w;
    }
    let v = ((d11 * d20 - d01 * d21) / denom).clamp(0.0, 1.0);
    let w = ((d00 * d21 - d01 * d20) / denom).clamp(0.0, 1.0 - v);
    [(1.0 - v - w) as f32, v as f32, w as f32]
}

/// The atlas at texture coordinates `uv`, bilinear between the four
/// nearest texels (clamped at the edges), as a linear colour.
fn sample_bilinear(atlas: &Atlas, uv: Vec2) -> [f32; 4] {
    let x = uv.x * atlas.width as f32 - 0.5;
    let y = uv.y * atlas.height as f32 - 0.5;
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let texel = |i: f32, j: f32| {
        let i = (i.max(0.0) as u32).min(atlas.width - 1);
        let j = (j.max(0.0) as u32).min(atlas.height - 1);
        decode(atlas.texels[(j * atlas.width + i) as usize])
    };
    let (a, b) = (texel(x0, y0), texel(x0 + 1.0, y0));
    let (c, d) = (texel(x0, y0 + 1.0), texel(x0 + 1.0, y0 + 1.0));
    std::array::from_fn(|k| {
        let top = a[k] + (b[k] - a[k]) * fx;
        let bottom = c[k] + (d[k] - c[k]) * fx;
        top + (bottom - top) * fy
    })
}

/// A linear colour as sRGB-encoded bytes (alpha stays linear).
pub fn encode(c: [f32; 4]) -> [u8; 4] {
    let srgb = |x: f32| {
        let x = x.clamp(0.0, 1.0);
        let s = if x <= 0.003_130_8 {
            12.92 * x
        } else {
            1.055 * x.powf(1.0 / 2.4) - 0.055
        };
        (s * 255.0).round() as u8
    };
    [
        srgb(c[0]),
        srgb(c[1]),
        srgb(c[2]),
        (c[3].clamp(0.0, 1.0) * 255.0).round() as u8,
    ]
}

/// sRGB-encoded bytes as a linear colour.
pub fn decode(t: [u8; 4]) -> [f32; 4] {
    let linear = |b: u8| {
        let s = f32::from(b) / 255.0;
        if s <= 0.040_45 {
            s / 12.92
        } else {
            ((s + 0.055) / 1.055).powf(2.4)
        }
    };
    [
        linear(t[0]),
        linear(t[1]),
        linear(t[2]),
        f32::from(t[3]) / 255.0,
    ]
}

/// The mesh as drawn with its baked colour: the texture coordinates of
/// every vertex, a textured triangle's corners its own vertices in white
/// (the texture holds its colour), the other triangles' vertices as they
/// were at the centre of the atlas's white block (their vertex colour
/// times white). Triangles, positions and features are the mesh's, in its
/// order.
pub fn drawn(mesh: &Mesh, baked: &Baked) -> (Mesh, Vec<Vec2>) {
    let white = Vec2::new(
        (WHITE / 2) as f32 / baked.atlas.width as f32,
        (WHITE / 2) as f32 / baked.atlas.height as f32,
    );
    let mut out = Mesh::default();
    let mut uvs = Vec::new();
    let mut shared: FxHashMap<u32, u32> = FxHashMap::default();
    let mut push = |out: &mut Mesh, i: usize, colour: Option<[f32; 4]>, uv: Vec2| {
        out.positions.push(mesh.positions[i]);
        if let Some(n) = mesh.normals.get(i) {
            out.normals.push(*n);
        }
        out.colors
            .push(colour.unwrap_or_else(|| mesh.colors.get(i).copied().unwrap_or([1.0; 4])));
        if let Some(f) = mesh.features.get(i) {
            out.features.push(*f);
        }
        uvs.push(uv);
        out.positions.len() as u32 - 1
    };
    for (k, t) in mesh.indices.chunks_exact(3).enumerate() {
        match baked.corners[k] {
            Some(uv) => {
                for c in 0..3 {
                    let at = push(&mut out, t[c] as usize, Some([1.0; 4]), uv[c]);
                    out.indices.push(at);
                }
            }
            None => {
                for &i in t {
                    let at = match shared.get(&i) {
                        Some(&at) => at,
                        None => {
                            let at = push(&mut out, i as usize, None, white);
                            shared.insert(i, at);
                            at
                        }
                    };
                    out.indices.push(at);
                }
            }
        }
    }
    (out, uvs)
}

#[cfg(test)]
mod tests {
    use super::*;

    const BAND: [f32; 4] = [0.05, 0.1, 0.4, 1.0];
    const WALL: [f32; 4] = [0.8, 0.75, 0.7, 1.0];

    /// A wall 10 m long and 3 m high in the plane z = 0, in horizontal
    /// bands 0.5 m high, every other one blue; its quad proxy 1 cm in
    /// front of it, with the wall's colour.
    fn banded_wall() -> (Mesh, Mesh) {
        let mut wall = Mesh::default();
        for b in 0..6 {
            let (y0, y1) = (b as f32 * 0.5, (b + 1) as f32 * 0.5);
            let colour = if b % 2 == 1 { BAND } else { WALL };
            push_rectangle(&mut wall, [0.0, y0], [10.0, y1], 0.0, colour);
        }
        let mut quad = Mesh::default();
        push_rectangle(&mut quad, [0.0, 0.0], [10.0, 3.0], 0.01, WALL);
        (wall, quad)
    }

    /// Adds the rectangle from `lo` to `hi` in the plane at `z`, facing +z,
    /// in `colour`, as feature 7.
    fn push_rectangle(mesh: &mut Mesh, lo: [f32; 2], hi: [f32; 2], z: f32, colour: [f32; 4]) {
        let base = mesh.positions.len() as u32;
        for (x, y) in [
            (lo[0], lo[1]),
            (hi[0], lo[1]),
            (hi[0], hi[1]),
            (lo[0], hi[1]),
        ] {
            mesh.positions.push(Vec3::new(x, y, z));
            mesh.colors.push(colour);
            mesh.normals.push(Vec3::Z);
            mesh.features.push(7);
        }
        mesh.indices
            .extend([base, base + 1, base + 2, base, base + 2, base + 3]);
    }

    /// The drawn colour at a point of the quad: the texture at its
    /// coordinates times the vertex colour.
    fn colour_on_quad(quad: &Mesh, baked: &Baked, p: Vec3) -> [f32; 4] {
        let (drawn, uvs) = drawn(quad, baked);
        for t in drawn.indices.chunks_exact(3) {
            let [a, b, c] = [0, 1, 2].map(|k| drawn.positions[t[k] as usize]);
            let w = barycentric(p, a, b, c);
            let inside = closest_point_on_triangle(p.into(), a.into(), b.into(), c.into())
                .distance(p.into())
                < 1e-5;
            if inside {
                let uv = uvs[t[0] as usize] * w[0]
                    + uvs[t[1] as usize] * w[1]
                    + uvs[t[2] as usize] * w[2];
                let texel = sample_bilinear(&baked.atlas, uv);
                let v = drawn.colors[t[0] as usize];
                return std::array::from_fn(|k| texel[k] * v[k]);
            }
        }
        panic!("{p} is not on the quad");
    }

    /// How the tests sample `chart` (of the mesh `proxy`): texels of
    /// `texel`, the source within 5 cm of it.
    fn sampling<'a>(chart: &'a Chart, texel: f32, proxy: &'a Proxy<'a>) -> Sampling<'a> {
        Sampling {
            chart,
            texel,
            reach: 0.05,
            row: chart.texels(texel)[0],
            proxy,
        }
    }

    fn options(texel: f32, max_size: u32) -> BakeOptions {
        BakeOptions {
            texel,
            reach: 0.05,
            max_size,
        }
    }

    fn near(a: [f32; 4], b: [f32; 4]) -> bool {
        (0..3).all(|k| (a[k] - b[k]).abs() < 0.02)
    }

    #[test]
    fn a_banded_wall_reduced_to_a_quad_keeps_its_bands() {
        let (wall, quad) = banded_wall();
        let sources = [Source {
            mesh: &wall,
            baked: None,
        }];
        let baked = bake(&quad, &sources, &options(0.05, 1024)).unwrap();
        // One chart of 200 x 60 texels and its gutter, beside the white block.
        assert!(baked.atlas.width <= 1024 && baked.atlas.height <= 1024);
        assert!(baked.atlas.width * baked.atlas.height >= 202 * 62);
        for b in 0..6 {
            let y = b as f32 * 0.5 + 0.25;
            let expected = if b % 2 == 1 { BAND } else { WALL };
            for x in [0.3, 5.0, 9.7] {
                let got = colour_on_quad(&quad, &baked, Vec3::new(x, y, 0.01));
                assert!(near(got, expected), "band {b} at x = {x}: {got:?}");
            }
        }
        // The geometry is the quad's, untouched.
        let (drawn, _) = drawn(&quad, &baked);
        assert_eq!(drawn.triangle_count(), quad.triangle_count());
        assert!(drawn.positions.iter().all(|p| quad.positions.contains(p)));
        assert_eq!(drawn.features, vec![7; drawn.positions.len()]);
    }

    /// Bars 0.3 m wide and 3 m high every metre in the plane z = d for each
    /// d of `depths`, the band's colour, under `banded_wall`'s quad: a
    /// lattice covering 30% of it straight on.
    fn bars(depths: &[f32]) -> Mesh {
        let mut bars = Mesh::default();
        for &z in depths {
            for b in 0..10 {
                let x = b as f32;
                push_rectangle(&mut bars, [x, 0.0], [x + 0.3, 3.0], z, BAND);
            }
        }
        bars
    }

    #[test]
    fn a_lattice_reduced_to_a_quad_keeps_its_cover_as_alpha() {
        // Bars 0.3 wide every metre, a hundredth of a metre behind a quad
        // over them, and a wall the quad covers whole: the wall's texels
        // are opaque (its glass too), the lattice's cover 30%, opaque on a
        // bar and transparent between, the colour there the bars'.
        let (mut wall, quad) = banded_wall();
        // Glass: a vertex colour's alpha is drawn opaque, not as a cover.
        for c in &mut wall.colors {
            c[3] = 0.45;
        }
        let solid = bake(
            &quad,
            &[Source {
                mesh: &wall,
                baked: None,
            }],
            &options(0.1, 1024),
        );
        assert!(solid.unwrap().atlas.texels.iter().all(|t| t[3] == 255));
        let bars = bars(&[0.0]);
        let sources = [Source {
            mesh: &bars,
            baked: None,
        }];
        let baked = bake(&quad, &sources, &options(0.1, 1024)).unwrap();
        let at = |x: f32| colour_on_quad(&quad, &baked, Vec3::new(x, 1.5, 0.01));
        assert_eq!(at(0.15)[3], 1.0);
        assert_eq!(at(0.65)[3], 0.0);
        assert!(near(at(0.65), BAND), "{:?}", at(0.65));
        let mean = (0..1000)
            .map(|k| at(0.005 + 0.01 * k as f32)[3])
            .sum::<f32>()
            / 1000.0;
        assert!((mean - 0.3).abs() < 0.02, "cover {mean}");
    }

    #[test]
    fn a_lattice_in_depth_covers_more_than_it_shows_straight_on() {
        // Two layers of the bars, one behind the other, 0.1 m and 0.9 m
        // deep in a box 1 m deep: straight on, the back bars hide behind
        // the front ones (30%); at a slant they stand apart, up to 60%.
        // The box's front face takes the cover seen from all round.
        let mut boxed = Mesh::cuboid(Vec3::new(0.0, 0.0, -1.0), Vec3::new(10.0, 3.0, 0.0), 1);
        boxed.colors = vec![WALL; boxed.positions.len()];
        boxed.features = vec![7; boxed.positions.len()];
        let layers = bars(&[-0.1, -0.9]);
        let sources = [Source {
            mesh: &layers,
            baked: None,
        }];
        let baked = bake(&boxed, &sources, &options(0.1, 1024)).unwrap();
        let mut sum = 0.0;
        for j in 0..30 {
            for i in 0..100 {
                let p = Vec3::new(0.05 + 0.1 * i as f32, 0.05 + 0.1 * j as f32, 0.0);
                sum += colour_on_quad(&boxed, &baked, p)[3];
            }
        }
        let cover = sum / 3000.0;
        assert!(cover > 0.38 && cover < 0.6, "cover {cover}");
    }

    #[test]
    fn a_wall_behind_a_lattice_takes_the_lattice_seen_at_a_slant() {
        // The two layers of bars 0.1 m and 0.9 m in front of a plain wall
        // (a crane's mast before the tower's face), the wall kept as its
        // quad: straight on the bars take 30% of it, at a slant they stand
        // apart. The wall's texels take the mean seen within 45 degrees
        // of its normal.
        let mut wall = Mesh::default();
        push_rectangle(&mut wall, [0.0, 0.0], [10.0, 3.0], 0.0, WALL);
        let mut source = bars(&[0.1, 0.9]);
        push_rectangle(&mut source, [0.0, 0.0], [10.0, 3.0], 0.0, WALL);
        let sources = [Source {
            mesh: &source,
            baked: None,
        }];
        let options = BakeOptions {
            reach: 1.0,
            ..options(0.1, 1024)
        };
        let baked = bake(&wall, &sources, &options).unwrap();
        let mut share = 0.0;
        for j in 0..30 {
            for i in 0..100 {
                let p = Vec3::new(0.05 + 0.1 * i as f32, 0.05 + 0.1 * j as f32, 0.0);
                let c = colour_on_quad(&wall, &baked, p);
                share += (WALL[0] - c[0]) / (WALL[0] - BAND[0]);
            }
        }
        let share = share / 3000.0;
        assert!(share > 0.38 && share < 0.6, "the bars' share {share}");
    }

    #[test]
    fn a_plate_behind_half_a_quad_keeps_its_cover_to_the_quads_edges() {
        // A plate behind the left half of the quad (3 m high), baked at
        // texels of 2.5 m: the quad's two rows of texels are 1.5 m each,
        // so the upper one does not reach past the quad's top edge and
        // count the empty space there as uncovered, and the gutter holds
        // the edge's cover, so filtering does not fade it. The plate's
        // texels are opaque up to the quad's edges.
        let (_, quad) = banded_wall();
        let mut plate = Mesh::default();
        push_rectangle(&mut plate, [0.0, 0.0], [5.0, 3.0], 0.0, BAND);
        let sources = [Source {
            mesh: &plate,
            baked: None,
        }];
        let baked = bake(&quad, &sources, &options(2.5, 1024)).unwrap();
        for j in 0..30 {
            for i in 0..37 {
                let p = Vec3::new(0.05 + 0.1 * i as f32, 0.05 + 0.1 * j as f32, 0.01);
                let alpha = colour_on_quad(&quad, &baked, p)[3];
                assert!(alpha > 0.99, "cover {alpha} at {p}");
            }
        }
        let right = colour_on_quad(&quad, &baked, Vec3::new(9.0, 1.5, 0.01))[3];
        assert!(right < 0.01, "cover {right} right of the plate");
    }

    #[test]
    fn the_atlas_stays_within_its_cap_at_coarser_texels() {
        let (wall, quad) = banded_wall();
        let sources = [Source {
            mesh: &wall,
            baked: None,
        }];
        let baked = bake(&quad, &sources, &options(0.001, 64)).unwrap();
        assert!(
            baked.atlas.width <= 64 && baked.atlas.height <= 64,
            "{}x{}",
            baked.atlas.width,
            baked.atlas.height
        );
        // Still 12 texels to a band or more: the bands are there.
        let got = colour_on_quad(&quad, &baked, Vec3::new(5.0, 0.75, 0.01));
        assert!(near(got, BAND), "{got:?}");
    }

    #[test]
    fn gutters_hold_the_colour_past_a_charts_edge() {
        let (wall, quad) = banded_wall();
        let sources = [Source {
            mesh: &wall,
            baked: None,
        }];
        let baked = bake(&quad, &sources, &options(0.1, 1024)).unwrap();
        let a = &baked.atlas;
        // Every texel around the chart (the gutter) is the wall's or the
        // band's colour, not the atlas's black background.
        let uv = baked.corners[0].unwrap();
        let lo = uv.iter().fold(Vec2::splat(f32::INFINITY), |m, x| m.min(*x));
        let hi = uv
            .iter()
            .fold(Vec2::splat(f32::NEG_INFINITY), |m, x| m.max(*x));
        let (x0, y0) = (
            (lo.x * a.width as f32) as u32,
            (lo.y * a.height as f32) as u32,
        );
        let (x1, y1) = (
            (hi.x * a.width as f32).ceil() as u32,
            (hi.y * a.height as f32).ceil() as u32,
        );
        for j in y0 - GUTTER..y1 + GUTTER {
            for i in [x0 - GUTTER, x1] {
                let t = decode(a.texels[(j * a.width + i) as usize]);
                assert!(
                    near(t, WALL) || near(t, BAND),
                    "gutter texel ({i}, {j}): {t:?}"
                );
            }
        }
    }

    #[test]
    fn kept_triangles_keep_their_vertex_colours_and_uniform_charts_shrink() {
        let (wall, _) = banded_wall();
        let sources = [Source {
            mesh: &wall,
            baked: None,
        }];
        // The wall itself kept as it is: nothing to bake.
        assert!(bake(&wall, &sources, &options(0.1, 256)).is_none());
        // A quad over one band only: one colour, one texel.
        let mut quad = Mesh::default();
        for (x, y) in [(0.0, 0.55), (10.0, 0.55), (10.0, 0.95), (0.0, 0.95)] {
            quad.positions.push(Vec3::new(x, y, 0.01));
            quad.colors.push(WALL);
        }
        quad.indices.extend([0, 1, 2, 0, 2, 3]);
        let baked = bake(&quad, &sources, &options(0.01, 1024)).unwrap();
        assert!(
            baked.atlas.width * baked.atlas.height <= 64,
            "{}x{}",
            baked.atlas.width,
            baked.atlas.height
        );
        assert!(near(
            colour_on_quad(&quad, &baked, Vec3::new(2.0, 0.7, 0.01)),
            BAND
        ));
    }

    /// A plain wall with bands 2 cm in front of it (a building's window
    /// bands), reduced to the wall alone: the wall's triangles are kept as
    /// they were, and take the bands seen in front of them.
    #[test]
    fn a_kept_wall_takes_the_bands_in_front_of_it() {
        let (banded, _) = banded_wall();
        let mut wall = Mesh::default();
        for (x, y) in [(0.0, 0.0), (10.0, 0.0), (10.0, 3.0), (0.0, 3.0)] {
            wall.positions.push(Vec3::new(x, y, 0.0));
            wall.colors.push(WALL);
        }
        wall.indices.extend([0, 1, 2, 0, 2, 3]);
        let mut source = wall.clone();
        let base = source.positions.len() as u32;
        source
            .positions
            .extend(banded.positions.iter().map(|p| *p + Vec3::Z * 0.02));
        source.colors.extend(&banded.colors);
        source
            .indices
            .extend(banded.indices.iter().map(|i| i + base));
        let sources = [Source {
            mesh: &source,
            baked: None,
        }];
        let baked = bake(&wall, &sources, &options(0.05, 1024)).unwrap();
        for (y, expected) in [(0.75, BAND), (1.25, WALL), (2.75, BAND)] {
            let got = colour_on_quad(&wall, &baked, Vec3::new(4.0, y, 0.0));
            assert!(near(got, expected), "at y = {y}: {got:?}");
        }
    }

    #[test]
    fn plain_blocks_are_filled_as_their_texels_would_be_sampled() {
        let (wall, quad) = banded_wall();
        let sources = [Source {
            mesh: &wall,
            baked: None,
        }];
        let surface = Surface::new(&sources).unwrap();
        let chart = &charts(&quad, &[0, 1])[0];
        for texel in [0.013, 0.07, 0.3] {
            let size = chart.texels(texel);
            let proxy = Proxy::new(&quad);
            let filled = surface.sample(chart, size, texel, 0.05, &proxy);
            let at = sampling(chart, texel, &proxy);
            for j in 0..size[1] {
                for i in 0..size[0] {
                    let one = surface.texel_average(&at, i, j, &mut None).unwrap();
                    assert_eq!(
                        filled[(j * size[0] + i) as usize],
                        one,
                        "texel {texel}: ({i}, {j})"
                    );
                }
            }
        }
    }

    #[test]
    fn a_texel_across_a_band_border_takes_each_colours_share() {
        let (wall, quad) = banded_wall();
        let sources = [Source {
            mesh: &wall,
            baked: None,
        }];
        let surface = Surface::new(&sources).unwrap();
        let chart = &charts(&quad, &[0, 1])[0];
        // Texels of 0.3 from the wall's foot: the second row spans 0.3 to
        // 0.6, the wall below the border at 0.5 and the band above it.
        let texel = 0.3;
        let size = chart.texels(texel);
        let proxy = Proxy::new(&quad);
        let at = sampling(chart, texel, &proxy);
        let row = (0..size[1])
            .find(|&j| {
                let p = chart.point(5.0, j as f32 + 0.5, texel);
                (0.3..0.6).contains(&p.y)
            })
            .unwrap();
        let got = decode(surface.texel_average(&at, 5, row, &mut None).unwrap());
        // A third of the texel's samples fall on the band: its colour is a
        // third of the way from the wall's to the band's, to within the
        // sRGB bytes.
        let expected: [f32; 4] = std::array::from_fn(|k| WALL[k] + (BAND[k] - WALL[k]) / 3.0);
        assert!(near(got, expected), "{got:?} against {expected:?}");
    }

    /// A 3 m square wall at z = 0 with a strip `[lo, hi]` across it (along
    /// y when `vertical`, else along x) 1 cm in front, and the wall's quad
    /// proxy in the strip's plane (so that the rays from all round meet
    /// the strip where they cross the proxy).
    fn wall_with_strip(vertical: bool, lo: f32, hi: f32) -> (Mesh, Mesh) {
        let mut source = Mesh::default();
        let quad = |mesh: &mut Mesh, corners: [(f32, f32); 4], z: f32, colour| {
            let base = mesh.positions.len() as u32;
            for (x, y) in corners {
                let (x, y) = if vertical { (x, y) } else { (y, x) };
                mesh.positions.push(Vec3::new(x, y, z));
                mesh.colors.push(colour);
                mesh.normals.push(Vec3::Z);
                mesh.features.push(7);
            }
            // Wound counter-clockwise seen from +z either way round.
            let order = if vertical {
                [0, 1, 2, 0, 2, 3]
            } else {
                [0, 2, 1, 0, 3, 2]
            };
            mesh.indices.extend(order.map(|k| base + k));
        };
        let square = [(0.0, 0.0), (3.0, 0.0), (3.0, 3.0), (0.0, 3.0)];
        quad(&mut source, square, 0.0, WALL);
        quad(
            &mut source,
            [(lo, 0.0), (hi, 0.0), (hi, 3.0), (lo, 3.0)],
            0.01,
            BAND,
        );
        let mut proxy = Mesh::default();
        quad(&mut proxy, square, 0.01, WALL);
        (source, proxy)
    }

    #[test]
    fn a_strip_thinner_than_a_third_of_a_texel_takes_its_share_wherever_it_lies() {
        // A mullion 9 cm wide across texels of 30 cm covers 30% of a texel.
        // A regular grid of n x n samples meets such a strip with a whole
        // number of its n columns, 0 or 1 of 3, 1 or 2 of 4, depending on
        // where it lies; the texel must take its share to within one
        // sample in n^2 wherever it lies, along either axis.
        let (texel, width) = (0.3, 0.09);
        for vertical in [true, false] {
            for step in 0..24 {
                let lo = 1.2 + step as f32 * 0.0125;
                let (source, proxy) = wall_with_strip(vertical, lo, lo + width);
                let sources = [Source {
                    mesh: &source,
                    baked: None,
                }];
                let surface = Surface::new(&sources).unwrap();
                let chart = &charts(&proxy, &[0, 1])[0];
                let size = chart.texels(texel);
                let baked = Proxy::new(&proxy);
                let at = sampling(chart, texel, &baked);
                // The texel in the middle of the wall whose square holds
                // the strip's start, and the share of its square the strip
                // covers.
                let along = |p: Vec3| if vertical { p.x } else { p.y };
                let (i, j) = (0..size[0])
                    .flat_map(|i| (0..size[1]).map(move |j| (i, j)))
                    .find(|&(i, j)| {
                        let a = chart.point(i as f32, j as f32, texel);
                        let b = chart.point(i as f32 + 1.0, j as f32 + 1.0, texel);
                        let across = |p: Vec3| if vertical { p.y } else { p.x };
                        (along(a).min(along(b))..along(a).max(along(b))).contains(&lo)
                            && (1.0..2.0).contains(&across(a))
                    })
                    .unwrap();
                let a = along(chart.point(i as f32, j as f32, texel));
                let b = along(chart.point(i as f32 + 1.0, j as f32 + 1.0, texel));
                let (from, to) = (a.min(b), a.max(b));
                let share = ((lo + width).min(to) - lo.max(from)) / texel;
                let got = decode(surface.texel_average(&at, i, j, &mut None).unwrap());
                let expected: [f32; 4] =
                    std::array::from_fn(|k| WALL[k] + (BAND[k] - WALL[k]) * share);
                let off = (0..3)
                    .map(|k| (got[k] - expected[k]).abs() / (BAND[k] - WALL[k]).abs())
                    .fold(0.0, f32::max);
                assert!(
                    off <= 1.0 / (SUBSAMPLES * SUBSAMPLES) as f32 + 0.02,
                    "vertical {vertical}, strip from {lo}: {got:?} against {expected:?} (share {share})"
                );
            }
        }
    }

    #[test]
    fn colours_survive_the_srgb_bytes() {
        for c in [0.0, 0.002, 0.1, 0.5, 0.9, 1.0] {
            let back = decode(encode([c, c, c, 1.0]));
            // Half a step of 8-bit sRGB: under 1% of the value.
            assert!((back[0] - c).abs() <= 0.01 * c.max(0.1), "{c}: {back:?}");
        }
    }
}
