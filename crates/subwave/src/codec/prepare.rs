//! From any input mesh to the semi-regular hierarchy the progressive codec takes
//! (`subwave encode`, `subwave eval`, the demo).
//!
//! A mesh that already has subdivision connectivity — 1-to-4 triangle splits or
//! Catmull-Clark quad splits, in any vertex order — is recognised by inverting the splitting
//! step (Maret 2003 Fig. 4.4, [`Hierarchy::detect`]) and coded as it is; any other mesh is
//! remeshed first ([`crate::remesh`], MAPS with the shrink-wrap fallback; Maret §4.2.3
//! "Decimation in meshes", Bertram §5.3).

use crate::hierarchy::Hierarchy;
use crate::mesh::Mesh;
use crate::remesh::{remesh_with_progress, RemeshOptions, Remeshed};
use crate::{Error, Result};

/// Default subdivision levels of the remesh of an irregular input.
pub const DEFAULT_LEVELS: u32 = 5;
/// Default base faces of the remesh of an irregular input.
pub const DEFAULT_BASE_FACES: usize = 200;

/// Options of [`prepare`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PrepareOptions {
    /// Levels: required levels of a detected hierarchy (`None`: as many as the mesh has), and
    /// the levels of a remesh (`None`: [`DEFAULT_LEVELS`]).
    pub levels: Option<u32>,
    /// Base faces of a remesh (`None`: [`DEFAULT_BASE_FACES`]); ignored for a detected
    /// hierarchy.
    pub base_faces: Option<usize>,
    /// Remesh to a quad hierarchy (Bertram's wavelets) instead of triangles.
    pub quads: bool,
    /// Feature edges of a remesh: dihedral angle in degrees.
    pub sharp_angle: Option<f64>,
    /// Remesh even if the input has subdivision connectivity.
    pub force_remesh: bool,
}

/// What [`prepare`] produced.
#[derive(Clone, Debug)]
pub struct Prepared {
    /// The hierarchy to code.
    pub hierarchy: Hierarchy,
    /// The remesh, if the input was remeshed (`None`: detected as it is).
    pub remeshed: Option<Remeshed>,
}

/// The hierarchy to code for `mesh`: detected if `mesh` is semi-regular (and the split kind
/// matches [`PrepareOptions::quads`]), else remeshed, non-manifold input being repaired
/// (split) rather than refused. `progress(stage, fraction)` reports the remesher's stages.
///
/// # Errors
/// [`Error::InvalidArgument`] for a mesh without faces; the remesher's errors (see
/// [`crate::remesh::remesh_with_progress`]).
pub fn prepare(
    mesh: &Mesh,
    opts: &PrepareOptions,
    progress: &mut dyn FnMut(&str, f64),
) -> Result<Prepared> {
    if mesh.num_faces() == 0 {
        return Err(Error::InvalidArgument(
            "the mesh has no faces: nothing to code".to_string(),
        ));
    }
    let shape_fits = if opts.quads {
        mesh.is_quad_mesh()
    } else {
        mesh.is_triangle_mesh()
    };
    if shape_fits && !opts.force_remesh {
        if let Ok((hierarchy, _)) = Hierarchy::detect(mesh, opts.levels) {
            return Ok(Prepared {
                hierarchy,
                remeshed: None,
            });
        }
    }
    let ro = RemeshOptions {
        levels: opts.levels.unwrap_or(DEFAULT_LEVELS),
        base_faces: opts.base_faces.unwrap_or(DEFAULT_BASE_FACES),
        quads: opts.quads,
        sharp_angle: opts.sharp_angle,
        repair: true,
        ..RemeshOptions::default()
    };
    let r = remesh_with_progress(mesh, &ro, progress)?;
    Ok(Prepared {
        hierarchy: r.hierarchy.clone(),
        remeshed: Some(r),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::generate;
    use crate::subdivision::refine::Split;

    #[test]
    fn semi_regular_input_is_detected_not_remeshed() {
        let m = generate::icosphere(3);
        let p = prepare(&m, &PrepareOptions::default(), &mut |_, _| {}).unwrap();
        assert!(p.remeshed.is_none());
        assert_eq!(p.hierarchy.levels(), 3);
        assert_eq!(p.hierarchy.base.num_faces(), 20);
        let p = prepare(
            &m,
            &PrepareOptions {
                levels: Some(2),
                ..Default::default()
            },
            &mut |_, _| {},
        )
        .unwrap();
        assert_eq!(p.hierarchy.levels(), 2);
    }

    #[test]
    fn irregular_input_is_remeshed() {
        // Odd grid sizes: no 1-to-4 structure (a regular even grid would be detected).
        let m = generate::torus(1.0, 0.4, 25, 13, true);
        let opts = PrepareOptions {
            levels: Some(2),
            base_faces: Some(64),
            ..Default::default()
        };
        let mut stages = Vec::new();
        let p = prepare(&m, &opts, &mut |s, _| stages.push(s.to_string())).unwrap();
        let r = p.remeshed.as_ref().expect("remeshed");
        assert_eq!(p.hierarchy.levels(), 2);
        assert_eq!(p.hierarchy.split, Split::Triangles);
        assert_eq!(r.mesh.num_vertices(), p.hierarchy.positions.len());
        assert!(!stages.is_empty());
    }

    #[test]
    fn empty_mesh_is_an_error() {
        let e = prepare(&Mesh::new(), &PrepareOptions::default(), &mut |_, _| {}).unwrap_err();
        assert!(e.to_string().contains("no faces"), "{e}");
    }
}
