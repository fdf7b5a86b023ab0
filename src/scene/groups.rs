//! Triangles grouped by material for the ray queries: the runs of consecutive triangles that
//! share one, each a group of the geometry, so that a hit names its material through its group.

/// The runs of consecutive triangles with one material, as groups of the geometry: a hit then
/// names its material through its group, where a per-triangle table costs a cache miss a hit
/// on a large mesh.
pub(super) struct MaterialGroups {
    /// [`crate::accel::Geometry::group_starts`].
    pub(super) starts: Vec<u32>,
    /// The material of each group.
    pub(super) materials: Vec<u32>,
}

impl MaterialGroups {
    /// More runs than this and the triangles are one group whose hits read the per-triangle
    /// table. Each group is a geometry of the ray-query backend, and Embree reads a hit
    /// candidate's geometry record, so many small groups cost more than the table saves: on
    /// a grid of 10,000 triangles in interleaved strips, 400,000 closest hits took about 1.02
    /// (64 groups), 1.08 (256), 1.17 (1024) and 1.3 (3456) times as long as with one group.
    /// Real scenes have a few dozen (the conference room 37, the Bitterli scenes 10-48).
    pub(super) const MAX: usize = 64;

    /// The material of a group whose triangles' materials differ.
    pub(super) const MIXED: u32 = u32::MAX;

    /// The groups of triangles whose materials are `triangle_materials`.
    pub(super) fn of(triangle_materials: &[u32]) -> Self {
        let mut groups = MaterialGroups {
            starts: Vec::new(),
            materials: triangle_materials.first().copied().into_iter().collect(),
        };
        for (i, pair) in triangle_materials.windows(2).enumerate() {
            if pair[0] != pair[1] {
                if groups.materials.len() == Self::MAX {
                    return MaterialGroups {
                        starts: Vec::new(),
                        materials: vec![Self::MIXED],
                    };
                }
                groups.starts.push(i as u32 + 1);
                groups.materials.push(pair[1]);
            }
        }
        groups
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn runs_of_one_material_are_the_groups() {
        let groups = MaterialGroups::of(&[4, 4, 4, 1, 1, 4, 7]);
        assert_eq!(groups.starts, [3, 5, 6]);
        assert_eq!(groups.materials, [4, 1, 4, 7]);
        let one = MaterialGroups::of(&[2; 9]);
        assert!(one.starts.is_empty());
        assert_eq!(one.materials, [2]);
        let none = MaterialGroups::of(&[]);
        assert!(none.starts.is_empty() && none.materials.is_empty());
    }

    #[test]
    fn materials_changing_too_often_make_one_mixed_group() {
        let at_most: Vec<u32> = (0..MaterialGroups::MAX as u32).collect();
        assert_eq!(MaterialGroups::of(&at_most).materials, at_most);
        let beyond: Vec<u32> = (0..=MaterialGroups::MAX as u32).map(|i| i % 2).collect();
        let groups = MaterialGroups::of(&beyond);
        assert!(groups.starts.is_empty());
        assert_eq!(groups.materials, [MaterialGroups::MIXED]);
    }
}
