//! Criterion benches of on-line evaluation: full reconstruction, contact-node
//! evaluation (particularize + 3 rows), for f32 and f64 storage.
//! `palpa lab bench eval` prints the same figures with the bandwidth ratio.

use criterion::{Criterion, criterion_group, criterion_main};
use palpa_core::synthetic::palpation_like;
use palpa_core::{ParamValue, Scalar};
use std::hint::black_box;

fn bench_precision<T: Scalar>(c: &mut Criterion, name: &str) {
    for (rows, modes) in [(30_000, 167), (60_000, 400)] {
        let m = palpation_like::<T>(rows, modes, 40, 1);
        let mut coeffs = vec![0.0; modes];
        let values = [
            ParamValue::Surface {
                triangle: 100,
                bary: [0.2, 0.3, 0.5],
            },
            ParamValue::Scalar(3.3),
        ];
        m.particularize(&values, &mut coeffs).expect("valid values");
        let mut out = vec![0.0; m.rows()];
        c.bench_function(&format!("reconstruct/{name}/{rows}x{modes}"), |b| {
            b.iter(|| m.reconstruct(black_box(&coeffs), &mut out));
        });
        let mut contact = [0.0; 3];
        c.bench_function(&format!("contact/{name}/{modes}"), |b| {
            b.iter(|| {
                m.particularize(black_box(&values), &mut coeffs)
                    .expect("valid values");
                m.reconstruct_range(3 * 1234, &coeffs, &mut contact);
                black_box(contact)
            });
        });
    }
}

fn benches(c: &mut Criterion) {
    bench_precision::<f32>(c, "f32");
    bench_precision::<f64>(c, "f64");
}

criterion_group!(eval, benches);
criterion_main!(eval);
