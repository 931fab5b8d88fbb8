use glam::{Mat4, Vec3};

/// An indexed triangle mesh: a polygon soup as far as any algorithm may
/// assume (no manifoldness, no connectivity). `normals` and `colors` are
/// either empty or one per position; colours are linear RGBA.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mesh {
    pub positions: Vec<Vec3>,
    pub normals: Vec<Vec3>,
    pub colors: Vec<[f32; 4]>,
    pub indices: Vec<u32>,
}

impl Mesh {
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    pub fn is_empty(&self) -> bool {
        self.indices.is_empty()
    }

    /// The triangles as corner positions.
    pub fn triangles(&self) -> impl Iterator<Item = [Vec3; 3]> + '_ {
        self.indices.chunks_exact(3).map(|t| {
            [
                self.positions[t[0] as usize],
                self.positions[t[1] as usize],
                self.positions[t[2] as usize],
            ]
        })
    }

    /// Axis-aligned bounds `(min, max)` of the referenced vertices, `None`
    /// for a mesh without triangles.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let mut it = self.indices.iter().map(|&i| self.positions[i as usize]);
        let first = it.next()?;
        Some(it.fold((first, first), |(lo, hi), p| (lo.min(p), hi.max(p))))
    }

    /// The mesh moved by `m` (normals by its inverse transpose).
    pub fn transformed(&self, m: &Mat4) -> Mesh {
        let normal_m = m.inverse().transpose();
        Mesh {
            positions: self
                .positions
                .iter()
                .map(|p| m.transform_point3(*p))
                .collect(),
            normals: self
                .normals
                .iter()
                .map(|n| normal_m.transform_vector3(*n).normalize_or_zero())
                .collect(),
            colors: self.colors.clone(),
            indices: self.indices.clone(),
        }
    }

    /// Checks the internal consistency a reader must guarantee: indices in
    /// range, a whole number of triangles, attribute lengths, finite values.
    pub fn validate(&self) -> Result<(), String> {
        if !self.indices.len().is_multiple_of(3) {
            return Err(format!(
                "{} indices is not a whole number of triangles",
                self.indices.len()
            ));
        }
        let n = self.positions.len();
        if let Some(i) = self.indices.iter().find(|&&i| i as usize >= n) {
            return Err(format!("index {i} is out of range ({n} vertices)"));
        }
        if !self.normals.is_empty() && self.normals.len() != n {
            return Err(format!("{} normals for {n} vertices", self.normals.len()));
        }
        if !self.colors.is_empty() && self.colors.len() != n {
            return Err(format!("{} colours for {n} vertices", self.colors.len()));
        }
        if let Some((i, p)) = self
            .positions
            .iter()
            .enumerate()
            .find(|(_, p)| !p.is_finite())
        {
            return Err(format!("vertex {i} has a non-finite coordinate {p}"));
        }
        Ok(())
    }
}
