//! Tissue files of formats 6 and 7, read into today's law: one group per sample.
//!
//! Before format 8 every sample had modes of its own (`mode_start` per sample, its
//! weights at `coeffs[mode · steps + j]`). That is the grouped layout with each
//! sample alone in its group, so the conversion only adds the per-sample arrays.

use serde::Deserialize;

use super::surfacelaw::{Refinement, SurfaceLawOptions};
use super::tissue::TissueLaw;
use super::tissue_shapes::Shapes;

/// The law as formats 6 and 7 store it (field order is the format).
#[derive(Deserialize)]
#[cfg_attr(test, derive(serde::Serialize))]
pub(super) struct TissueLawV7 {
    options: SurfaceLawOptions,
    rows_mm: Vec<[f32; 3]>,
    samples_mm: Vec<[f32; 3]>,
    skipped_mm: Vec<[f32; 3]>,
    edge_ends: Vec<[u32; 2]>,
    refinement: Refinement,
    steps: u32,
    ratio: Vec<f32>,
    stiffness_n_per_mm: Vec<f32>,
    correction_mm: Vec<f32>,
    segments: Vec<u32>,
    reach: Vec<u32>,
    stopped: Vec<String>,
    rank: u32,
    mode_start: Vec<u32>,
    shape: Shapes,
    shape_scale: Vec<f32>,
    coeffs: Vec<f32>,
    truncation_bound_mm: f64,
    tolerance_mm: f64,
    build_s: f64,
    compress_s: f64,
}

impl From<TissueLawV7> for TissueLaw {
    fn from(o: TissueLawV7) -> TissueLaw {
        let samples = o.mode_start.len().saturating_sub(1) as u32;
        TissueLaw {
            group: (0..samples).collect(),
            coeff_start: o.mode_start.iter().map(|&m| m * o.steps).collect(),
            options: o.options,
            rows_mm: o.rows_mm,
            samples_mm: o.samples_mm,
            skipped_mm: o.skipped_mm,
            edge_ends: o.edge_ends,
            refinement: o.refinement,
            steps: o.steps,
            ratio: o.ratio,
            stiffness_n_per_mm: o.stiffness_n_per_mm,
            correction_mm: o.correction_mm,
            segments: o.segments,
            reach: o.reach,
            stopped: o.stopped,
            rank: o.rank,
            mode_start: o.mode_start,
            shape: o.shape,
            shape_scale: o.shape_scale,
            coeffs: o.coeffs,
            truncation_bound_mm: o.truncation_bound_mm,
            tolerance_mm: o.tolerance_mm,
            build_s: o.build_s,
            compress_s: o.compress_s,
            mesh_xxh3: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::framed::Body;
    use crate::pgd::subsplit::SubSplit;
    use crate::pgd::tissue::MAGIC;
    use crate::pgd::tissue_predict::RowPrediction;
    use crate::pgd::tissue_weights::Weights;

    /// A law of one group per sample, as format 7 wrote it.
    fn as_v7(l: &TissueLaw) -> TissueLawV7 {
        TissueLawV7 {
            options: l.options,
            rows_mm: l.rows_mm.clone(),
            samples_mm: l.samples_mm.clone(),
            skipped_mm: l.skipped_mm.clone(),
            edge_ends: l.edge_ends.clone(),
            refinement: l.refinement.clone(),
            steps: l.steps,
            ratio: l.ratio.clone(),
            stiffness_n_per_mm: l.stiffness_n_per_mm.clone(),
            correction_mm: l.correction_mm.clone(),
            segments: l.segments.clone(),
            reach: l.reach.clone(),
            stopped: l.stopped.clone(),
            rank: l.rank,
            mode_start: l.mode_start.clone(),
            shape: l.shape.clone(),
            shape_scale: l.shape_scale.clone(),
            coeffs: l.coeffs.clone(),
            truncation_bound_mm: l.truncation_bound_mm,
            tolerance_mm: l.tolerance_mm,
            build_s: l.build_s,
            compress_s: l.compress_s,
        }
    }

    /// A version 14 file's body: the law, its weights, the second level, the band, the
    /// organ mesh's fingerprint (version 13: the same without the fingerprint).
    type Raw = (
        TissueLaw,
        Weights,
        SubSplit,
        Vec<crate::pgd::surfacelaw::BandEdge>,
        Option<u64>,
    );

    #[test]
    fn version_6_and_7_files_load_with_each_sample_its_own_group() {
        let law = crate::pgd::tissue_knobs::tests::law();
        let dir = tempfile::tempdir().expect("tempdir");
        for (version, body) in [(7, Body::Deflated), (6, Body::Plain)] {
            let path = dir.path().join(format!("v{version}.tissue"));
            crate::framed::write(&path, MAGIC, (version, body), &as_v7(&law)).expect("writes");
            let back = TissueLaw::load(&path).expect("loads");
            assert_eq!(back, law, "version {version}");
            assert_eq!(back.group, vec![0, 1, 2]);
        }
        // Version 8 (today's fields, deflated) and 9 (LZMA, shapes by plane) load as
        // they are; today's files are version 14, and a version this palpa does not
        // know is named.
        let path = dir.path().join("v8.tissue");
        crate::framed::write(&path, MAGIC, (8, Body::Deflated), &law).expect("writes");
        assert_eq!(TissueLaw::load(&path).expect("loads"), law);
        let path = dir.path().join("v9.tissue");
        let planes = TissueLaw {
            shape: law.shape.to_planes(),
            ..law.clone()
        };
        crate::framed::write(&path, MAGIC, (9, Body::Lzma), &planes).expect("writes");
        assert_eq!(TissueLaw::load(&path).expect("loads"), law);
        // Weights that are not all halves are stored in f32, halves in sixteen bits.
        let (half, _) = law.with_half_weights();
        // Version 12 is today's without the band ([`BandEdge`]), which comes last;
        // version 11 is 12 with the shapes by plane; version 10 is 11 without the second
        // level ([`SubSplit`]), which comes after the weights.
        for (law, single) in [(&law, true), (&half, false)] {
            let path = dir.path().join("v14.tissue");
            law.save(&path).expect("saves");
            let bytes = std::fs::read(&path).expect("reads");
            assert_eq!(&bytes[8..12], &14u32.to_le_bytes());
            let (stored, weights, sub, band, mesh): Raw =
                crate::framed::read(&bytes, MAGIC, &[(14, Body::Lzma)]).expect("raw");
            assert!(band.is_empty());
            assert_eq!(mesh, None);
            let predicted = RowPrediction::new(&law.rows_mm).encode(&law.shape);
            assert_eq!(Some(&stored.shape), predicted.as_ref(), "shapes as misses");
            assert_ne!(stored.shape, law.shape);
            assert!(stored.coeffs.is_empty(), "weights stored after the law");
            assert_eq!(matches!(weights, Weights::Single(_)), single);
            assert!(sub.is_empty());
            assert_eq!(&TissueLaw::load(&path).expect("loads"), law);
            let v13 = dir.path().join("v13.tissue");
            crate::framed::write(
                &v13,
                MAGIC,
                (13, Body::Lzma),
                &(&stored, &weights, &sub, &band),
            )
            .expect("writes");
            assert_eq!(&TissueLaw::load(&v13).expect("loads"), law);
            let v12 = dir.path().join("v12.tissue");
            crate::framed::write(&v12, MAGIC, (12, Body::Lzma), &(&stored, &weights, &sub))
                .expect("writes");
            assert_eq!(&TissueLaw::load(&v12).expect("loads"), law);
            let by_plane = TissueLaw {
                shape: law.shape.to_planes(),
                ..stored.clone()
            };
            let v11 = dir.path().join("v11.tissue");
            crate::framed::write(&v11, MAGIC, (11, Body::Lzma), &(&by_plane, &weights, &sub))
                .expect("writes");
            assert_eq!(&TissueLaw::load(&v11).expect("loads"), law);
            let v10 = dir.path().join("v10.tissue");
            crate::framed::write(&v10, MAGIC, (10, Body::Lzma), &(&by_plane, &weights))
                .expect("writes");
            assert_eq!(&TissueLaw::load(&v10).expect("loads"), law);
        }
        // A version 14 body whose shapes are no whole number of modes is named.
        let bytes = std::fs::read(dir.path().join("v14.tissue")).expect("reads");
        let (mut stored, weights, sub, band, mesh): Raw =
            crate::framed::read(&bytes, MAGIC, &[(14, Body::Lzma)]).expect("raw");
        stored.shape = stored.shape.prefix(stored.shape.len() - 1);
        let torn = dir.path().join("torn.tissue");
        crate::framed::write(
            &torn,
            MAGIC,
            (14, Body::Lzma),
            &(&stored, &weights, &sub, &band, mesh),
        )
        .expect("writes");
        let e = TissueLaw::load(&torn).expect_err("a torn shape");
        assert!(e.to_string().contains("whole number of modes"), "{e}");
        let path = dir.path().join("v15.tissue");
        crate::framed::write(&path, MAGIC, (15, Body::Lzma), &law).expect("writes");
        let e = TissueLaw::load(&path).expect_err("version 15");
        assert!(e.to_string().contains("version 15"), "{e}");
    }
}
