//! A conserved pair of species, eliminated before a separated solve.
//!
//! If every reaction keeps `a z_i + b z_j` fixed (`a ν_i + b ν_j = 0` with whole
//! `a, b > 0`), the state lives on the line `z_i = (C − b z_j)/a`, `C = a z_i(0) + b z_j(0)`.
//! On the box that line is a diagonal, and a separated (tensor-train) representation of
//! a distribution on a diagonal needs a rank as large as the line is long: the DSMTS
//! dimerisation of 1000 monomers did not finish in 10 minutes. Eliminating `z_i` leaves
//! one coordinate less and an exact network: each factor of `z_i` becomes a factor of
//! `z_j` (`z` and `C(z, k)` a product of affine factors, an affine factor another
//! affine factor); Hill and saturation factors of `z_i` are not affine in `z_j`, and then
//! the pair is left alone. [`Reduced::expand`] gives back the original species'
//! moments, the eliminated one's marginal by the map `z_i = offset + slope · z_j`.

use super::moments::Moments;
use super::network::{Factor, Network};

/// A network with one species of a conserved pair eliminated.
#[derive(Debug, Clone, PartialEq)]
pub struct Reduced {
    pub network: Network,
    /// The eliminated species (index in the original network).
    pub eliminated: usize,
    /// The species it is written with (index in the original network).
    pub from: usize,
    /// `z_eliminated = offset + slope · z_from`.
    pub offset: f64,
    pub slope: f64,
    /// Copy numbers the eliminated species can take: `0..=max`.
    pub max: usize,
}

fn gcd(a: i64, b: i64) -> i64 {
    if b == 0 { a.abs() } else { gcd(b, a % b) }
}

/// The first conserved pair whose elimination is exact, if any (see the module doc).
/// The covariance of the first two species must stay recoverable, so a species among
/// the first two is eliminated only in favour of the other.
pub fn reduce(network: &Network) -> Option<Reduced> {
    let d = network.species.len();
    for i in 0..d {
        for j in 0..d {
            if i == j || (i < 2 && j >= 2) {
                continue;
            }
            if let Some(r) = try_pair(network, i, j) {
                return Some(r);
            }
        }
    }
    None
}

fn try_pair(network: &Network, i: usize, j: usize) -> Option<Reduced> {
    // The ratio a : b from the first reaction that moves either.
    let first = network
        .reactions
        .iter()
        .find(|r| r.change[i] != 0 || r.change[j] != 0)?;
    let (ni, nj) = (i64::from(first.change[i]), i64::from(first.change[j]));
    if ni == 0 || nj == 0 || ni.signum() == nj.signum() {
        return None;
    }
    let g = gcd(ni, nj);
    let (a, b) = (nj.abs() / g, ni.abs() / g);
    if !network
        .reactions
        .iter()
        .all(|r| a * i64::from(r.change[i]) + b * i64::from(r.change[j]) == 0)
    {
        return None;
    }
    let (af, bf) = (a as f64, b as f64);
    let c = af * network.species[i].initial as f64 + bf * network.species[j].initial as f64;
    let (offset, slope) = (c / af, -bf / af);
    // Factors of i rewritten as factors of j; refuse the pair if one is not affine.
    let mut reactions = network.reactions.clone();
    for r in &mut reactions {
        let mut factors = Vec::with_capacity(r.factors.len());
        for &(s, f) in &r.factors {
            if s != i {
                factors.push((s, f));
                continue;
            }
            match f {
                Factor::Linear => factors.push((j, Factor::Affine { offset, slope })),
                Factor::Affine {
                    offset: o,
                    slope: k,
                } => factors.push((
                    j,
                    Factor::Affine {
                        offset: o + k * offset,
                        slope: k * slope,
                    },
                )),
                Factor::Binomial { k } => {
                    for m in 0..k {
                        let w = f64::from(m + 1);
                        factors.push((
                            j,
                            Factor::Affine {
                                offset: (offset - f64::from(m)) / w,
                                slope: slope / w,
                            },
                        ));
                    }
                }
                _ => return None,
            }
        }
        r.factors = factors;
    }
    // Drop species i and renumber.
    let renumber = |s: usize| if s > i { s - 1 } else { s };
    for r in &mut reactions {
        r.change.remove(i);
        for f in &mut r.factors {
            f.0 = renumber(f.0);
        }
    }
    let mut species = network.species.clone();
    species.remove(i);
    let mut reduced = network.clone();
    reduced.species = species;
    reduced.reactions = reactions;
    Some(Reduced {
        network: reduced,
        eliminated: i,
        from: j,
        offset,
        slope,
        max: offset.max(0.0).floor() as usize,
    })
}

impl Reduced {
    /// The original network's moments from the reduced network's.
    pub fn expand(&self, m: &Moments) -> Moments {
        let d = self.network.species.len() + 1;
        let at = |s: usize| if s > self.eliminated { s - 1 } else { s };
        let from = &m.marginals[at(self.from)];
        let mut eliminated = vec![0.0; self.max + 1];
        for (z, &q) in from.iter().enumerate() {
            let y = self.offset + self.slope * z as f64;
            let k = y.round();
            if (y - k).abs() < 1e-9 && k >= 0.0 && (k as usize) <= self.max {
                eliminated[k as usize] += q;
            }
        }
        let marginals: Vec<Vec<f64>> = (0..d)
            .map(|s| {
                if s == self.eliminated {
                    eliminated.clone()
                } else {
                    m.marginals[at(s)].clone()
                }
            })
            .collect();
        // E[z₀ z₁] (unnormalized): from the pair's own line, or the reduced moments.
        let e01 = if d < 2 {
            0.0
        } else if (self.eliminated < 2) && (self.from < 2) {
            from.iter()
                .enumerate()
                .map(|(z, &q)| q * z as f64 * (self.offset + self.slope * z as f64))
                .sum()
        } else {
            (m.cov01 + m.mean[0] * m.mean[1]) * m.mass
        };
        Moments::from_marginals(m.t, marginals, e01, m.mass)
    }
}
