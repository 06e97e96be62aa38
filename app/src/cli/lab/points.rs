//! `palpa lab tissue points`: seeded held-out points for `tissue build --cover` and
//! `tissue check --at`, printed as `X,Y,Z,…`.

use std::path::PathBuf;

use anyhow::bail;
use clap::Args;
use palpa_core::rng::Rng;
use palpa_core::tissue::law::TissueLaw;

use crate::cli::args::OrganArgs;
use crate::cli::tissue::points::{
    check_heldout, faces_area, faces_next_to_fixed, heldout_point, points_in, split_faces,
    surface_points,
};

#[derive(Debug, Args)]
pub struct PointsArgs {
    #[command(flatten)]
    organ: OrganArgs,
    #[arg(long, default_value_t = 16)]
    heldout: usize,
    #[arg(long, default_value_t = 7)]
    seed: u64,
    /// Draw them inside the split triangles of this tissue file only: what a
    /// refinement buys, measured where it split (`tissue check --at` on the file and
    /// on the one it refined).
    #[arg(long)]
    split_of: Option<PathBuf>,
    /// Draw them inside the palpable triangles that touch the fixed region only (a
    /// corner fixed, so never pressed: the blend there renormalizes over the pressed
    /// corners). The default draw leaves this band out.
    #[arg(long, conflicts_with = "split_of")]
    next_to_fixed: bool,
}

/// `palpa lab tissue points`.
pub fn points(args: &PointsArgs) -> anyhow::Result<()> {
    if args.heldout == 0 {
        bail!("--heldout 0: expected at least one point");
    }
    let organ = args.organ.mesh()?;
    let points = match &args.split_of {
        None if args.next_to_fixed => {
            let faces = faces_next_to_fixed(&organ);
            if faces.is_empty() {
                bail!("this organ has no palpable triangle with a fixed corner");
            }
            let palpable: Vec<usize> = (0..organ.boundary.len())
                .filter(|&f| organ.palpable[f])
                .collect();
            let all_held = |tri: &[u32; 3]| tri.iter().all(|&v| organ.fixed[v as usize]);
            let held_faces = faces
                .iter()
                .filter(|&&f| all_held(&organ.boundary[f]))
                .count();
            eprintln!(
                "tissue points: {} triangles touch the fixed region, {:.1} % of the \
                 palpable surface's area ({held_faces} with all three corners held)",
                faces.len(),
                100.0 * faces_area(&organ, &faces) / faces_area(&organ, &palpable)
            );
            // Drawn as `points_in` draws them (the same seed gives the same points),
            // keeping each point's triangle to say which lie where nothing moves.
            check_heldout(args.heldout)?;
            let mut rng = Rng::seed(args.seed);
            let drawn: Vec<_> = (0..args.heldout)
                .map(|_| heldout_point(&organ, &faces, &mut rng))
                .collect();
            let held = drawn.iter().filter(|(_, tri, _)| all_held(tri)).count();
            if held > 0 {
                eprintln!(
                    "tissue points: {held} of the {} points lie in a triangle whose three \
                     corners are held: nothing moves there (`tissue check` reports them as \
                     held)",
                    drawn.len()
                );
            }
            drawn.into_iter().map(|(p, _, _)| p).collect()
        }
        None => surface_points(&organ, args.heldout, args.seed)?,
        Some(file) => {
            let law = TissueLaw::load(file)?;
            law.check_organ(&organ)?;
            let faces = split_faces(&organ, &law)?;
            points_in(&organ, &faces, args.heldout, args.seed)?
        }
    };
    let text: Vec<String> = points.iter().flatten().map(|c| format!("{c:.4}")).collect();
    println!("{}", text.join(","));
    Ok(())
}
