//! The palpation scene on the shipped asset: the palpable map, the contact law, and the
//! errors for models that are not palpation scenes.

use palpa_core::file;
use palpa_core::rng::Rng;
use palpa_core::scene::{ContactError, PalpationScene, SceneError};

fn scene() -> PalpationScene {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/liver-coarse.palpa");
    PalpationScene::new(file::load_any(&path).expect("asset loads"))
        .expect("asset is a palpation scene")
}

#[test]
fn palpable_points_from_surface_triangles_are_the_same_points() {
    let s = scene();
    let mut rng = Rng::seed(7);
    let mut palpable = 0;
    for t in 0..s.triangles().len() as u32 {
        let a = rng.uniform();
        let b = rng.uniform() * (1.0 - a);
        let bary = [a, b, 1.0 - a - b];
        let Some(p) = s.palpable_point(t, bary) else {
            continue;
        };
        palpable += 1;
        // The same physical point, computed from the boundary triangle's own corners.
        let tri = s.triangles()[t as usize];
        let want: [f64; 3] = std::array::from_fn(|c| {
            (0..3)
                .map(|i| bary[i] * f64::from(s.vertices_mm()[tri[i] as usize][c]))
                .sum()
        });
        let (got, n) = s.frame(&p);
        for c in 0..3 {
            assert!(
                (got[c] - want[c]).abs() < 1e-9,
                "triangle {t}: {got:?} vs {want:?}"
            );
        }
        assert!((n.iter().map(|x| x * x).sum::<f64>() - 1.0).abs() < 1e-9);
    }
    // The palpable region is a proper part of the surface.
    assert!(
        palpable > 100 && palpable < s.triangles().len(),
        "{palpable} palpable triangles"
    );
}

#[test]
fn pressing_to_a_depth_with_the_force_from_the_compliance_gives_that_depth() {
    let s = scene();
    let mut scratch = s.contact_scratch();
    let n = s.modes();
    let mut coeffs = vec![0.0; n];
    let mut u = vec![0.0; s.model().rows()];
    let mut rng = Rng::seed(11);
    let mut checked = 0;
    while checked < 20 {
        let t = rng.below(s.triangles().len()) as u32;
        let Some(p) = s.palpable_point(t, [1.0 / 3.0; 3]) else {
            continue;
        };
        let c = s
            .contact(&p, n, &mut scratch)
            .expect("full model: positive compliance");
        // Soft tissue, 5 mm tool, E = 160 kPa: Hertz gives c ≈ 1/(2 E* a) ≈ 0.5 mm/N
        // locally; the whole organ moving adds to it. Anything outside this is wrong.
        assert!(
            c.compliance_mm_per_n > 0.05 && c.compliance_mm_per_n < 20.0,
            "compliance {} mm/N",
            c.compliance_mm_per_n
        );
        let depth_mm = 6.0;
        let force_n = depth_mm / c.compliance_mm_per_n;
        s.displacement(&p, c.push_dir.map(|d| d * force_n), &mut coeffs, &mut u)
            .expect("evaluates");
        let vs = s.probe_vertices(&p);
        let along: f64 = (0..3)
            .map(|i| {
                p.bary[i]
                    * (0..3)
                        .map(|k| u[3 * vs[i] as usize + k] * c.push_dir[k])
                        .sum::<f64>()
            })
            .sum();
        // The contact law itself: the contact point's own displacement under that
        // force is the depth (f32 storage: relative 1e-5).
        let felt: f64 = (0..3)
            .map(|k| c.unit_displacement_mm_per_n[k] * force_n * c.push_dir[k])
            .sum();
        assert!((felt - depth_mm).abs() < 1e-4 * depth_mm, "felt {felt} mm");
        // The rendered surface interpolates its corner rows linearly, while the contact
        // point's displacement is the P2 point value under the tool (the nodal scene's
        // compliance table): the drawn dimple at the point is shallower, by less than
        // 40 % on the coarse mesh (measured 27 % at worst over these points).
        assert!(
            along > 0.6 * depth_mm && along < 1.0001 * depth_mm,
            "drawn depth {along} mm, pressed {depth_mm}"
        );
        checked += 1;
    }
}

#[test]
fn too_many_modes_are_clamped_and_one_mode_is_either_positive_or_reported() {
    let s = scene();
    let mut scratch = s.contact_scratch();
    let p = s
        .palpable_point(
            (0..s.triangles().len() as u32)
                .find(|&t| s.palpable_point(t, [1.0 / 3.0; 3]).is_some())
                .expect("a palpable triangle"),
            [1.0 / 3.0; 3],
        )
        .expect("palpable");
    let all = s.contact(&p, s.modes(), &mut scratch).expect("all modes");
    let more = s
        .contact(&p, 10 * s.modes(), &mut scratch)
        .expect("clamped");
    assert_eq!(all, more);
    match s.contact(&p, 1, &mut scratch) {
        Ok(c) => assert!(c.compliance_mm_per_n > 0.0),
        Err(ContactError::NonPositiveCompliance { modes, .. }) => assert_eq!(modes, 1),
        Err(e) => panic!("unexpected error {e}"),
    }
}

#[test]
fn a_model_that_is_not_a_palpation_scene_is_refused_with_its_reason() {
    let m = palpa_tests::small_model::<f32>(30, 4, 3);
    match PalpationScene::new(file::AnyModel::F32(m)) {
        Err(SceneError::NotPalpation { axes, .. }) => assert!(axes > 0),
        other => panic!("expected NotPalpation, got {other:?}"),
    }
}
