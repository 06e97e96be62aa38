//! The default scene in `assets/` comes from the current code and mesh: its recorded
//! inputs (organ mesh hash, element, material, tool radius) are recomputed here and
//! must match, and its surface geometry must be the current mesh's.

use palpa_core::axis::Discretization;
use palpa_core::fe::{Element, Material};
use palpa_core::file;
use palpa_core::organ::liver::{Liver, spacing_mm};
use palpa_core::organ::{Level, mesh_organ};
use palpa_core::pgd::palpation::{describe, describe_get};

#[test]
fn the_default_scene_matches_the_current_mesh_and_settings() {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/liver-coarse.palpa");
    let model = file::load::<f32>(&path).expect("assets/liver-coarse.palpa loads as an f32 scene");
    let desc = &model.provenance().mesh;
    let liver = Liver::default();
    let organ = mesh_organ(
        &liver,
        spacing_mm(Level::Coarse),
        &liver.fixed_region(),
        &liver.palpable_region(),
    );
    let radius: f64 = describe_get(desc, "radius_mm")
        .expect("radius recorded")
        .parse()
        .expect("number");
    let now = describe(
        &organ,
        "coarse",
        Element::P2,
        Material::default(),
        radius,
        describe_get(desc, "update") == Some("true"),
    );
    assert_eq!(
        desc, &now,
        "the asset was computed from another mesh or settings: run scripts/make-assets.sh"
    );
    assert_eq!(
        model.provenance().input_hash,
        format!("{:016x}", xxhash_rust::xxh3::xxh3_64(now.as_bytes()))
    );
    // The load axis covers the current palpable surface, face for face.
    let Discretization::SurfaceLoad {
        palpable: faces, ..
    } = &model.axes()[0].info.discretization
    else {
        panic!("the default scene is a nodal-load vademecum");
    };
    let palpable: usize = organ.palpable.iter().filter(|&&p| p).count();
    assert_eq!(faces.iter().filter(|&&p| p).count(), palpable);
    assert!(palpable > 100);
    let near = model
        .near()
        .expect("the default scene carries its near field");
    assert!(near.band_nodes.len() > 1000 && !near.table_values.is_empty());
    // Surface-only: every row belongs to a boundary node, and the geometry is there.
    assert_eq!(model.geometry().nodes.len() * 3, model.rows());
    assert!(!model.geometry().surface.is_empty());
    assert!(
        !model.tradeoff().is_empty(),
        "the tradeoff table the accuracy knob reads"
    );
    // A phone budget of 20 MB.
    assert!(std::fs::metadata(&path).expect("size").len() < 20_000_000);
}
