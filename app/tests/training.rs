//! Find the nodule on the built-in liver: a hidden nodule stiffens the force the loop
//! sends where it lies and nowhere beyond its table's reach; the surface drawn stays
//! at the pressed depth; a mark reveals it and is scored; headless, the cycle runs
//! from the command line's options and reports the force with and without it along
//! the probe path.

use std::time::Duration;

use palpa_app::force::{NoHaptics, PressMode, ProbeCommand};
use palpa_app::offscreen::{HeadlessOptions, HiddenNodule, settle};
use palpa_app::scenes;
use palpa_app::session::Session;
use palpa_core::pgd::nodule::amplification::EffectCurve;

/// The built-in liver's session, its training mode on.
fn session() -> Session {
    scenes::built_in()
        .expect("built-in scene")
        .session(Box::new(NoHaptics))
        .expect("session")
}

/// The loop's answer to `c`.
fn answer(s: &Session, c: ProbeCommand) -> palpa_app::force::ForceSample {
    s.force.command(c);
    let t0 = std::time::Instant::now();
    while s.force.latest().command != c && t0.elapsed() < Duration::from_secs(2) {
        std::thread::sleep(Duration::from_micros(200));
    }
    let sample = s.force.latest();
    assert_eq!(sample.command, c, "the loop answered");
    sample
}

/// `c` without the nodule.
fn without_nodule(mut c: ProbeCommand) -> ProbeCommand {
    c.nodule = EffectCurve::default();
    c
}

/// The first seed from 1 whose nodule changes the force by more than `effect`.
fn seed_above(s: &mut Session, effect: f64) -> u64 {
    let t = s
        .training
        .as_mut()
        .expect("the built-in liver offers the training");
    (1..100)
        .find(|&seed| {
            t.hide(Some(seed), 0.0).expect("hides");
            t.trial.as_ref().expect("a case").case.peak_effect > effect
        })
        .expect("a nodule to feel")
}

#[test]
fn a_hidden_nodule_stiffens_the_force_over_it_and_a_mark_reveals_and_scores_it() {
    let mut s = session();
    let seed = seed_above(&mut s, 0.08);
    let t = s.training.as_ref().expect("training");
    let case = t.trial.as_ref().expect("a case").case.clone();
    // Over the nodule: the force at a depth `d` is the nodule-free one times
    // `1 + e A(d)`, `A` the amplification the table's power of the built-in tissue
    // gives.
    let (over, _) = s
        .scene
        .closest_palpable(case.surface_mm)
        .expect("a palpable point");
    let effect = t.effect_at(&over);
    assert!(effect > 0.02, "seed {seed}: {effect} over the nodule");
    s.controls.probe = Some(over);
    s.controls.pressing = true;
    s.controls.mode = PressMode::Depth;
    s.controls.depth_mm = 6.0;
    let with = answer(&s, s.command());
    let curve = t.curve_at(&s.scene, &over);
    assert!(
        t.amplifies(),
        "the built-in table holds the built-in tissue's power"
    );
    assert!(curve.len > 0 && curve.effect == effect, "{curve:?}");
    assert_eq!(
        with.command.nodule, curve,
        "the input side puts the curve into the command"
    );
    let without = answer(&s, without_nodule(s.command()));
    let ratio = f64::from(with.magnitude_n / without.magnitude_n);
    let gain = 1.0 + curve.at(6.0);
    assert!(
        (gain - 1.0 - f64::from(effect)).abs() > 0.01 * f64::from(effect),
        "amplified: {gain} against 1 + {effect}"
    );
    assert!((ratio - gain).abs() < 1e-5, "{ratio} against {gain}");
    assert!((f64::from(with.nodule_gain) - gain).abs() < 1e-5);
    // The surface drawn is the nodule-free one at the same depth under the tool.
    assert_eq!(with.depth_mm, without.depth_mm);
    assert_eq!(with.linear_n, without.linear_n);
    // Under a force the nodule holds the probe shallower.
    s.controls.mode = PressMode::Force;
    s.controls.force_n = 2.0;
    let firm = answer(&s, s.command());
    let soft = answer(&s, without_nodule(s.command()));
    assert!(
        firm.depth_mm < soft.depth_mm,
        "{} mm against {} mm without",
        firm.depth_mm,
        soft.depth_mm
    );
    // ... at the depth where the tissue's force there times the gain there is the
    // force asked.
    s.controls.mode = PressMode::Depth;
    s.controls.depth_mm = firm.depth_mm;
    let there = answer(&s, without_nodule(s.command()));
    let gain = 1.0 + curve.at(f64::from(firm.depth_mm));
    let f = f64::from(there.magnitude_n) * gain;
    assert!((f - 2.0).abs() < 2e-3, "{f} N against the 2 N asked");
    s.controls.depth_mm = 6.0;
    // Far from it (90 mm along x, three times the table's reach) only the far field's
    // trace is left (measured: the table 0.40 % of the force, the full FE 0.20 %).
    let far_mm = [0, 1, 2].map(|d| case.surface_mm[d] + if d == 0 { 90.0 } else { 0.0 });
    let (far, _) = s.scene.closest_palpable(far_mm).expect("a palpable point");
    let e = t.effect_at(&far);
    assert!((0.0..1e-2).contains(&e), "{e}");
    // The largest force counts; a mark reveals the nodule and scores it.
    s.controls.mode = PressMode::Depth;
    s.force.command(s.command());
    settle(&s, Duration::from_secs(2));
    s.frame();
    let largest = s
        .training
        .as_ref()
        .expect("training")
        .trial
        .as_ref()
        .expect("case")
        .largest_force_n();
    assert!(largest >= f64::from(with.magnitude_n) * 0.999, "{largest}");
    assert!(s.frame().nodule.is_none(), "hidden until marked");
    let score = s.mark().expect("marks").expect("a score");
    assert!(score.distance_mm < 0.5, "marked over it: {score:?}");
    let again = s.mark().expect("marks").expect("the score");
    assert_eq!(again, score, "once revealed, the score stands");
    assert_eq!(s.training.as_ref().expect("training").scores.len(), 1);
    let shown = s.frame().nodule.expect("revealed");
    assert_eq!(shown.radius_mm, case.nodule().radius_mm as f32);
    // The trainer's map: 1 + effect at the scene's vertices, its top within the case's
    // peak; deeper, the tissue's effect is amplified (a new generation of values).
    let t = s.training.as_mut().expect("training");
    let peak = 1.0 + case.peak_effect as f32;
    let (ratios, generation) = t.vertex_ratios(&s.scene, 0.0);
    let top = ratios.iter().copied().fold(0.0, f32::max);
    assert!(ratios.iter().all(|&r| r >= 1.0 - 1e-4), "no softening");
    assert!(top > 1.0 && top <= peak + 1e-3, "{top} against {peak}");
    assert_eq!(t.peak_ratio(), top);
    let (deep, deeper) = t.vertex_ratios(&s.scene, 8.0);
    let deep_top = deep.iter().copied().fold(0.0, f32::max);
    assert!(deeper != generation, "a new map");
    assert!(
        ((deep_top - 1.0) / (top - 1.0) - 1.0).abs() > 0.01,
        "amplified: {deep_top} against {top}"
    );
}

#[test]
fn headless_hides_marks_and_reports_the_force_with_and_without_the_nodule() {
    let options = |map: bool| HeadlessOptions {
        scene: "liver".into(),
        frames: 30,
        size: (480, 320),
        probe_path: None,
        out: None,
        modes: None,
        colormap_mm: None,
        deform_on: None,
        fps: 0.0,
        ui: false,
        display: palpa_app::layout::Display::default(),
        nodule: Some(HiddenNodule::Seed(4)),
        mark: true,
        stiffness_map: map,
    };
    let (report, plain) = palpa_app::offscreen::run(&options(false)).expect("renders");
    let n = report.nodule.expect("the nodule reported");
    assert_eq!(n.seed, Some(4));
    assert!(!n.path.is_empty(), "the default path presses");
    for p in &n.path {
        assert!(p.force_n >= p.force_without_nodule_n, "{p:?}");
        assert!(p.force_n <= p.force_without_nodule_n * (1.0 + n.peak_effect as f32) * 1.0001);
    }
    let score = n.score.expect("marked at the last frame");
    assert!(score.distance_mm.is_finite());
    // The stiffness map colours the surface.
    let (_, map) = palpa_app::offscreen::run(&options(true)).expect("renders");
    assert_ne!(plain.rgba, map.rgba, "the map changes the picture");
    // Marking needs a nodule to mark.
    let e = palpa_app::offscreen::run(&HeadlessOptions {
        nodule: None,
        ..options(false)
    })
    .expect_err("nothing hidden");
    assert!(e.to_string().contains("--mark"), "{e}");
}

/// The surface drawn with a hidden nodule: the nodule-free one at the same depth under
/// the tool, and away from it swayed with the larger force, `1 + e_t (1 − exp(−r²/ℓ²))`
/// times it (`e_t` the effect at the press).
#[test]
fn the_surface_sways_with_a_hidden_nodules_force() {
    let mut s = session();
    seed_above(&mut s, 0.08);
    let t = s.training.as_ref().expect("training");
    let (over, _) = s
        .scene
        .closest_palpable(t.trial.as_ref().expect("a case").case.surface_mm)
        .expect("a palpable point");
    let curve = t.curve_at(&s.scene, &over);
    s.controls.probe = Some(over);
    s.controls.pressing = true;
    s.controls.mode = PressMode::Depth;
    s.controls.depth_mm = 6.0;
    let drawn = |s: &mut Session, c| {
        answer(s, c);
        s.force.command(c);
        let _ = s.frame();
        s.deformed_mm().to_vec()
    };
    let training = s.training.take();
    let c = without_nodule(s.controls.command());
    let free = drawn(&mut s, c);
    s.training = training;
    let c = s.command();
    let nodular = drawn(&mut s, c);
    let at = s.scene.frame(&over).0;
    let e_t = curve.at(6.0);
    let (mut checked, mut swayed) = (0, 0.0f64);
    for ((f, n), r) in free.iter().zip(&nodular).zip(s.scene.vertices_mm()) {
        let r2: f64 = (0..3).map(|k| (f64::from(r[k]) - at[k]).powi(2)).sum();
        let g = palpa_core::pgd::nodule::table::surface_gain(e_t, r2);
        for k in 0..3 {
            let (uf, un) = (f64::from(f[k] - r[k]), f64::from(n[k] - r[k]));
            // f32 positions about 100 mm: a few ulps.
            assert!(
                (un - g * uf).abs() < 2e-5 * 100.0,
                "{un} against {g} x {uf}"
            );
            if uf.abs() > 0.05 {
                checked += 1;
                swayed = swayed.max(un / uf);
            }
        }
    }
    assert!(
        checked > 100 && swayed > 1.0 + 0.9 * e_t,
        "{checked} {swayed} {e_t}"
    );
}
