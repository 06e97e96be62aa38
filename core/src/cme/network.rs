//! Reaction networks with separable propensities, read from TOML.
//!
//! A network has species (each with a copy-number box `0..max`), parameters (a value,
//! or a range with a grid: an extra coordinate of the PGD meta-model), and reactions: a
//! change vector and a propensity that is a **product of one-species factors** times a
//! rate (a constant times named parameters):
//!
//! `a_r(z; p) = k_r · Π_q p_q · Π_i f_{r,i}(z_i)`.
//!
//! Separability is what makes the CME operator a short sum of Kronecker products (see
//! `docs/methods.md` §3); a factor that depends on several species is refused.
//!
//! ```toml
//! name = "cascade"
//! [[species]]
//! name = "z1"
//! max = 200          # states 0..199 (or "auto": FSP grows the box until the leak is small)
//! initial = 0
//! [[parameters]]
//! name = "delta"
//! range = [0.01, 0.045]
//! grid = 36
//! value = 0.02       # used when no value is given on the command line
//! [[reactions]]
//! change = { z1 = -1 }
//! rate = ["delta"]   # numbers and parameter names, multiplied
//! factors = [{ species = "z1", kind = "linear" }]
//! ```
//!
//! Factor kinds: `linear` (z), `binomial` (`z(z−1)···(z−k+1)/k!` with `k`: mass action
//! of order k in one species, the CME's count of distinct k-tuples), `affine`
//! (`max(0, offset + slope·z)`: a count that runs out, such as `100 − 2z`),
//! `hill_repression` (β/(β + γ zⁿ)), `saturation` (βz/(βz + γ)), `hill_activation`
//! (βzⁿ/(βzⁿ + γ)). A reaction may have several factors of one species: they multiply.
//! A reaction with no factor has a constant propensity.
//!
//! **No count goes below zero.** A reaction that lowers species i by `c` must have a
//! propensity that vanishes for `z_i < c` through its own factors of species i (`linear`
//! for `c = 1`, `binomial` with `k ≥ c`, …); otherwise the network is refused naming the
//! reaction. A constant-rate reaction that consumes a species is the classic mistake
//! this catches: the SSA would drive the count negative and FSP would see a leak that no
//! box can close.

use std::collections::BTreeMap;

use serde::Deserialize;
use thiserror::Error;

/// Why a network description was refused.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum NetworkError {
    #[error("{source_name}: {message}")]
    Syntax {
        source_name: String,
        message: String,
    },
    #[error("{source_name}: {what}")]
    Invalid { source_name: String, what: String },
    #[error(
        "unknown built-in network {0:?}; expected toggle, cascade or signaling-cascade-D (D = 2..20)"
    )]
    UnknownBuiltIn(String),
}

/// The largest initial copy number a network may declare (2³⁰): far past any box
/// the FSP or PGD solvers hold (10⁷ states), and small enough that a path of the
/// stochastic simulation keeps exact integer counts.
pub const MAX_INITIAL: usize = 1 << 30;

/// One species.
#[derive(Debug, Clone, PartialEq)]
pub struct Species {
    pub name: String,
    /// Box size: copy numbers `0..max`; `None`: automatic.
    pub max: Option<usize>,
    pub initial: usize,
}

/// One parameter: a fixed value, or a range that becomes a coordinate.
#[derive(Debug, Clone, PartialEq)]
pub struct Parameter {
    pub name: String,
    pub value: f64,
    /// `(lo, hi, grid points)` when the parameter is an extra coordinate.
    pub range: Option<(f64, f64, usize)>,
    /// How the grid points are spread over the range.
    pub spacing: Spacing,
}

/// Spread of a parameter grid. A rate δ that sets a mean copy number `~1/δ` moves the
/// distribution evenly in `1/δ` (`reciprocal`); its spread `~√(1/δ)` grows with the
/// mean, so steps even in `1/√δ` (`reciprocal-sqrt`) move the mean by the same fraction
/// of the spread everywhere (`Δ(1/δ)/√(1/δ) = 2Δ(1/√δ)`), which is what sets the
/// interpolation error between grid points. On the cascade to t = 600, a 36-point
/// reciprocal grid gave a joint L1 of 2e-2 between its two highest-δ points and 7e-4
/// between its lowest.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Spacing {
    #[default]
    Linear,
    Log,
    Reciprocal,
    ReciprocalSqrt,
}

impl Parameter {
    /// The grid points of a range parameter (increasing), `None` for a fixed one.
    pub fn grid(&self) -> Option<Vec<f64>> {
        let (lo, hi, n) = self.range?;
        let s = |i: usize| i as f64 / (n - 1) as f64;
        let mut g: Vec<f64> = (0..n)
            .map(|i| match self.spacing {
                Spacing::Linear => lo + (hi - lo) * s(i),
                Spacing::Log if lo > 0.0 => lo * (hi / lo).powf(s(i)),
                Spacing::Reciprocal if lo > 0.0 => 1.0 / (1.0 / lo + (1.0 / hi - 1.0 / lo) * s(i)),
                Spacing::ReciprocalSqrt if lo > 0.0 => {
                    let (a, b) = (1.0 / lo.sqrt(), 1.0 / hi.sqrt());
                    (a + (b - a) * s(i)).powi(-2)
                }
                _ => lo + (hi - lo) * s(i),
            })
            .collect();
        g[0] = lo;
        g[n - 1] = hi;
        Some(g)
    }
}

/// A one-species factor of a propensity.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Factor {
    Linear,
    /// `z(z−1)···(z−k+1)/k!`.
    Binomial {
        k: u32,
    },
    /// `max(0, offset + slope·z)`.
    Affine {
        offset: f64,
        slope: f64,
    },
    HillRepression {
        beta: f64,
        gamma: f64,
        n: f64,
    },
    Saturation {
        beta: f64,
        gamma: f64,
    },
    HillActivation {
        beta: f64,
        gamma: f64,
        n: f64,
    },
}

impl Factor {
    pub fn eval(&self, z: f64) -> f64 {
        match *self {
            Factor::Linear => z,
            Factor::Binomial { k } => {
                let mut v = 1.0;
                for j in 0..k {
                    v *= (z - f64::from(j)) / f64::from(j + 1);
                }
                v.max(0.0)
            }
            Factor::Affine { offset, slope } => (offset + slope * z).max(0.0),
            Factor::HillRepression { beta, gamma, n } => beta / (beta + gamma * z.powf(n)),
            Factor::Saturation { beta, gamma } => beta * z / (beta * z + gamma),
            Factor::HillActivation { beta, gamma, n } => {
                let zn = z.powf(n);
                if zn == 0.0 {
                    0.0
                } else {
                    beta * zn / (beta * zn + gamma)
                }
            }
        }
    }
}

/// One reaction.
#[derive(Debug, Clone, PartialEq)]
pub struct Reaction {
    pub name: String,
    /// Change of each species' copy number (one entry per species).
    pub change: Vec<i32>,
    /// Constant part of the rate.
    pub constant: f64,
    /// Parameters multiplying the rate (indices into [`Network::parameters`]).
    pub params: Vec<usize>,
    /// `(species index, factor)`; several factors of one species multiply.
    pub factors: Vec<(usize, Factor)>,
}

impl Reaction {
    /// The product of this reaction's factors of species `i` at copy number `z`
    /// (1 where it has none).
    pub fn species_factor(&self, i: usize, z: f64) -> f64 {
        self.factors
            .iter()
            .filter(|(s, _)| *s == i)
            .map(|(_, f)| f.eval(z))
            .product()
    }
}

/// A reaction network with separable propensities.
#[derive(Debug, Clone, PartialEq)]
pub struct Network {
    pub name: String,
    pub species: Vec<Species>,
    pub parameters: Vec<Parameter>,
    pub reactions: Vec<Reaction>,
    /// Species held at a constant amount (an SBML model's boundary and constant
    /// species, and those no reaction changes): constants of the laws, not coordinates
    /// of the state; their distribution is a point mass at this amount.
    pub fixed: Vec<(String, f64)>,
}

impl Network {
    /// Propensity of reaction `r` at state `z` with parameter values `p`.
    pub fn propensity(&self, r: usize, z: &[i64], p: &[f64]) -> f64 {
        let re = &self.reactions[r];
        let mut a = re.constant;
        for &q in &re.params {
            a *= p[q];
        }
        for (i, f) in &re.factors {
            a *= f.eval(z[*i] as f64);
        }
        a
    }

    /// What to say of reaction `r`'s propensity `a` at state `z` when it is not a finite
    /// number (rates so large that they overflow double precision): the solvers refuse
    /// it with this message instead of stepping forever or drawing NaN.
    pub fn overflow_message(&self, r: usize, z: &[i64], a: f64) -> String {
        let state = self
            .species
            .iter()
            .zip(z)
            .map(|(s, v)| format!("{} = {v}", s.name))
            .collect::<Vec<_>>()
            .join(", ");
        format!(
            "reaction {:?}: its propensity at ({state}) is {a}, beyond double precision \
             (largest {:e}): the rates overflow; lower them or measure time in smaller units",
            self.reactions[r].name,
            f64::MAX
        )
    }

    /// The first reaction whose propensity can overflow on the box `sizes` at the
    /// parameter values `p`: each factor at its largest over its species' box. What the
    /// separated solvers multiply is exactly these per-species factors.
    pub fn overflow_on_box(&self, p: &[f64], sizes: &[usize]) -> Option<String> {
        for (r, re) in self.reactions.iter().enumerate() {
            let mut a = re.constant;
            let mut at = vec![0i64; self.species.len()];
            for &q in &re.params {
                a *= p[q];
            }
            for (i, &m) in sizes.iter().enumerate() {
                if !re.factors.iter().any(|(s, _)| *s == i) {
                    continue;
                }
                let (z, f) = (0..m)
                    .map(|z| (z, re.species_factor(i, z as f64).abs()))
                    .fold((0, 0.0f64), |best, x| if x.1 > best.1 { x } else { best });
                at[i] = z as i64;
                a *= f;
            }
            if !a.is_finite() {
                return Some(self.overflow_message(r, &at, a));
            }
        }
        None
    }

    /// Refuses a reaction that could take a species below zero: where it lowers
    /// species i by `c`, its factors of i must vanish at every `z_i < c`.
    fn check_no_negative_counts(&self) -> Result<(), NetworkError> {
        for re in &self.reactions {
            for (i, &c) in re.change.iter().enumerate() {
                if c >= 0 {
                    continue;
                }
                let need = c.unsigned_abs();
                if let Some(z) = (0..need).find(|&z| re.species_factor(i, f64::from(z)) != 0.0) {
                    let s = &self.species[i].name;
                    return Err(self.invalid(format!(
                        "{}: lowers {s} by {need} but its propensity does not vanish at {s} = {z}, \
                         so {s} could go below zero; give it a factor of {s} that is zero \
                         there (linear for one copy, binomial with k = {need} for {need})",
                        re.name
                    )));
                }
            }
        }
        Ok(())
    }

    /// The parameters' values: the defaults, overridden by `set` (name, value).
    /// A value outside a range parameter's range is clamped and reported.
    pub fn parameter_values(
        &self,
        set: &[(String, f64)],
    ) -> Result<(Vec<f64>, Vec<String>), NetworkError> {
        let mut v: Vec<f64> = self.parameters.iter().map(|p| p.value).collect();
        let mut clamped = Vec::new();
        for (name, value) in set {
            let Some(i) = self.parameters.iter().position(|p| &p.name == name) else {
                return Err(self.invalid(format!(
                    "no parameter {name:?}; the network has {}",
                    self.parameters
                        .iter()
                        .map(|p| p.name.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                )));
            };
            if !value.is_finite() || *value < 0.0 {
                return Err(self.invalid(format!(
                    "parameter {name} = {value}: expected a finite value ≥ 0"
                )));
            }
            let mut x = *value;
            if let Some((lo, hi, _)) = self.parameters[i].range
                && !(lo..=hi).contains(&x)
            {
                x = x.clamp(lo, hi);
                clamped.push(format!(
                    "{name} = {value} is outside its trained range [{lo}, {hi}]: clamped to {x}"
                ));
            }
            v[i] = x;
        }
        Ok((v, clamped))
    }

    /// Whether some reaction raises species `i`, and by how much at most.
    pub fn largest_increase(&self, i: usize) -> i32 {
        self.reactions
            .iter()
            .map(|r| r.change[i])
            .max()
            .unwrap_or(0)
            .max(0)
    }

    fn invalid(&self, what: String) -> NetworkError {
        NetworkError::Invalid {
            source_name: self.name.clone(),
            what,
        }
    }

    /// A network from its parts, checked as a TOML one is (names, boxes, no negative
    /// counts); `source_name` names it in errors.
    pub fn from_parts(
        name: String,
        species: Vec<Species>,
        parameters: Vec<Parameter>,
        reactions: Vec<Reaction>,
        source_name: &str,
    ) -> Result<Self, NetworkError> {
        let bad = |what: String| NetworkError::Invalid {
            source_name: source_name.to_string(),
            what,
        };
        if species.is_empty() {
            return Err(bad("a network needs at least one species".into()));
        }
        if reactions.is_empty() {
            return Err(bad("a network needs at least one reaction".into()));
        }
        // Every reader ends here, so what one reader lets through (an SBML amount of
        // 1e30, a value of 1e400 read as infinity) is refused as a TOML file's is.
        for s in &species {
            if s.initial > MAX_INITIAL {
                return Err(bad(format!(
                    "species {}: initial {}: expected at most {MAX_INITIAL} molecules",
                    s.name, s.initial
                )));
            }
        }
        for p in &parameters {
            if !(p.value.is_finite() && p.value >= 0.0) {
                return Err(bad(format!(
                    "parameter {}: value {}: expected a finite value ≥ 0",
                    p.name, p.value
                )));
            }
        }
        for r in &reactions {
            if !(r.constant.is_finite() && r.constant >= 0.0) {
                return Err(bad(format!(
                    "{}: rate constant {}: expected a finite value ≥ 0",
                    r.name, r.constant
                )));
            }
        }
        let network = Network {
            name,
            species,
            parameters,
            reactions,
            fixed: Vec::new(),
        };
        network.check_no_negative_counts().map_err(|e| match e {
            NetworkError::Invalid { what, .. } => bad(what),
            other => other,
        })?;
        Ok(network)
    }

    /// The network as TOML that [`Network::from_toml`] reads back to the same network
    /// (species held fixed are listed in a comment: they are constants of the laws).
    pub fn to_toml(&self) -> String {
        use std::fmt::Write as _;
        let mut s = format!("name = {:?}\n", self.name);
        for (name, amount) in &self.fixed {
            let _ = writeln!(
                s,
                "# held fixed (a constant of the laws): {name} = {amount}"
            );
        }
        for sp in &self.species {
            let max = sp.max.map_or("\"auto\"".to_string(), |m| m.to_string());
            let _ = write!(
                s,
                "\n[[species]]\nname = {:?}\nmax = {max}\ninitial = {}\n",
                sp.name, sp.initial
            );
        }
        for p in &self.parameters {
            let _ = write!(
                s,
                "\n[[parameters]]\nname = {:?}\nvalue = {:?}\n",
                p.name, p.value
            );
            if let Some((lo, hi, n)) = p.range {
                let spacing = match p.spacing {
                    Spacing::Linear => "linear",
                    Spacing::Log => "log",
                    Spacing::Reciprocal => "reciprocal",
                    Spacing::ReciprocalSqrt => "reciprocal-sqrt",
                };
                let _ = write!(
                    s,
                    "range = [{lo:?}, {hi:?}]\ngrid = {n}\nspacing = {spacing:?}\n"
                );
            }
        }
        for r in &self.reactions {
            let change: Vec<String> = r
                .change
                .iter()
                .enumerate()
                .filter(|(_, c)| **c != 0)
                .map(|(i, c)| format!("{:?} = {c}", self.species[i].name))
                .collect();
            let mut rate = vec![format!("{:?}", r.constant)];
            rate.extend(
                r.params
                    .iter()
                    .map(|&q| format!("{:?}", self.parameters[q].name)),
            );
            let factors: Vec<String> = r
                .factors
                .iter()
                .map(|(i, f)| {
                    let sp = format!("species = {:?}", self.species[*i].name);
                    match *f {
                        Factor::Linear => format!("{{ {sp}, kind = \"linear\" }}"),
                        Factor::Binomial { k } => format!("{{ {sp}, kind = \"binomial\", k = {k} }}"),
                        Factor::Affine { offset, slope } => format!(
                            "{{ {sp}, kind = \"affine\", offset = {offset:?}, slope = {slope:?} }}"
                        ),
                        Factor::HillRepression { beta, gamma, n } => format!(
                            "{{ {sp}, kind = \"hill_repression\", beta = {beta:?}, gamma = {gamma:?}, n = {n:?} }}"
                        ),
                        Factor::Saturation { beta, gamma } => format!(
                            "{{ {sp}, kind = \"saturation\", beta = {beta:?}, gamma = {gamma:?} }}"
                        ),
                        Factor::HillActivation { beta, gamma, n } => format!(
                            "{{ {sp}, kind = \"hill_activation\", beta = {beta:?}, gamma = {gamma:?}, n = {n:?} }}"
                        ),
                    }
                })
                .collect();
            let _ = write!(
                s,
                "\n[[reactions]]\nname = {:?}\nchange = {{ {} }}\nrate = [{}]\n",
                r.name,
                change.join(", "),
                rate.join(", ")
            );
            if !factors.is_empty() {
                let _ = writeln!(s, "factors = [{}]", factors.join(", "));
            }
        }
        s
    }

    /// Parses a TOML description; `source_name` names it in errors (a file path).
    pub fn from_toml(text: &str, source_name: &str) -> Result<Self, NetworkError> {
        let raw: RawNetwork = toml::from_str(text).map_err(|e| NetworkError::Syntax {
            source_name: source_name.to_string(),
            message: line_message(text, &e),
        })?;
        raw.build(source_name)
    }

    /// A built-in network by name: `toggle`, `cascade`, `signaling-cascade-D`.
    pub fn built_in(name: &str) -> Result<Self, NetworkError> {
        let text = match name {
            "toggle" => TOGGLE.to_string(),
            "cascade" => CASCADE.to_string(),
            _ => match name
                .strip_prefix("signaling-cascade-")
                .and_then(|d| d.parse::<usize>().ok())
            {
                Some(d) if (2..=20).contains(&d) => signaling_cascade(d),
                _ => return Err(NetworkError::UnknownBuiltIn(name.to_string())),
            },
        };
        Self::from_toml(&text, name)
    }
}

fn line_message(text: &str, e: &toml::de::Error) -> String {
    match e.span() {
        Some(span) => {
            let line = text[..span.start.min(text.len())].matches('\n').count() + 1;
            format!("line {line}: {}", e.message())
        }
        None => e.message().to_string(),
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawNetwork {
    name: String,
    species: Vec<RawSpecies>,
    #[serde(default)]
    parameters: Vec<RawParameter>,
    reactions: Vec<RawReaction>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSpecies {
    name: String,
    max: toml::Value,
    #[serde(default)]
    initial: usize,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawParameter {
    name: String,
    value: Option<f64>,
    range: Option<[f64; 2]>,
    grid: Option<usize>,
    spacing: Option<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawReaction {
    #[serde(default)]
    name: Option<String>,
    change: BTreeMap<String, i32>,
    #[serde(default)]
    rate: Vec<toml::Value>,
    #[serde(default)]
    factors: Vec<RawFactor>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawFactor {
    species: toml::Value,
    kind: String,
    beta: Option<f64>,
    gamma: Option<f64>,
    n: Option<f64>,
    k: Option<i64>,
    offset: Option<f64>,
    slope: Option<f64>,
}

/// Builds a checked part from its raw TOML form; `bad` turns a message into the
/// error naming the network's source.
type Bad<'a> = &'a dyn Fn(String) -> NetworkError;

impl RawNetwork {
    fn build(self, src: &str) -> Result<Network, NetworkError> {
        let bad = |what: String| NetworkError::Invalid {
            source_name: src.to_string(),
            what,
        };
        if self.species.is_empty() {
            return Err(bad("a network needs at least one species".into()));
        }
        let mut species: Vec<Species> = Vec::new();
        for s in &self.species {
            if species.iter().any(|x| x.name == s.name) {
                return Err(bad(format!("species {} is declared twice", s.name)));
            }
            species.push(s.build(&bad)?);
        }
        let parameters = self
            .parameters
            .iter()
            .map(|p| p.build(&bad))
            .collect::<Result<Vec<_>, _>>()?;
        let reactions = self
            .reactions
            .iter()
            .enumerate()
            .map(|(k, r)| r.build(k, &species, &parameters, &bad))
            .collect::<Result<Vec<_>, _>>()?;
        Network::from_parts(self.name, species, parameters, reactions, src)
    }
}

impl RawSpecies {
    fn build(&self, bad: Bad<'_>) -> Result<Species, NetworkError> {
        let s = self;
        let max = match &s.max {
            toml::Value::Integer(m) if *m >= 2 && *m <= 1 << 20 => Some(*m as usize),
            toml::Value::String(a) if a == "auto" => None,
            other => {
                return Err(bad(format!(
                    "species {}: max = {other}: expected an integer in 2..=1048576 or \"auto\"",
                    s.name
                )));
            }
        };
        if max.is_some_and(|m| s.initial >= m) {
            return Err(bad(format!(
                "species {}: initial {} is outside its box 0..{}",
                s.name,
                s.initial,
                max.unwrap_or(0)
            )));
        }
        Ok(Species {
            name: s.name.clone(),
            max,
            initial: s.initial,
        })
    }
}

impl RawParameter {
    fn build(&self, bad: Bad<'_>) -> Result<Parameter, NetworkError> {
        let p = self;
        let range = match (p.range, p.grid) {
            (Some([lo, hi]), g) => {
                if !(lo.is_finite() && hi.is_finite() && 0.0 <= lo && lo < hi) {
                    return Err(bad(format!(
                        "parameter {}: range [{lo}, {hi}]: expected 0 ≤ lo < hi",
                        p.name
                    )));
                }
                let g = g.unwrap_or(17);
                if g < 2 {
                    return Err(bad(format!(
                        "parameter {}: grid = {g}: expected at least 2 points",
                        p.name
                    )));
                }
                Some((lo, hi, g))
            }
            (None, Some(_)) => {
                return Err(bad(format!("parameter {}: a grid needs a range", p.name)));
            }
            (None, None) => None,
        };
        let value = match (p.value, range) {
            (Some(v), _) if v.is_finite() && v >= 0.0 => v,
            (Some(v), _) => {
                return Err(bad(format!(
                    "parameter {}: value {v}: expected a finite value ≥ 0",
                    p.name
                )));
            }
            (None, Some((lo, hi, _))) => 0.5 * (lo + hi),
            (None, None) => {
                return Err(bad(format!(
                    "parameter {} needs a value or a range",
                    p.name
                )));
            }
        };
        let spacing = match p.spacing.as_deref() {
            None | Some("linear") => Spacing::Linear,
            Some("log" | "reciprocal" | "reciprocal-sqrt") if range.is_some_and(|r| r.0 <= 0.0) => {
                return Err(bad(format!(
                    "parameter {}: {} spacing needs a range above 0",
                    p.name,
                    p.spacing.as_deref().unwrap_or_default()
                )));
            }
            Some("log") => Spacing::Log,
            Some("reciprocal") => Spacing::Reciprocal,
            Some("reciprocal-sqrt") => Spacing::ReciprocalSqrt,
            Some(other) => {
                return Err(bad(format!(
                    "parameter {}: spacing {other:?}: expected linear, log, reciprocal or reciprocal-sqrt",
                    p.name
                )));
            }
        };
        Ok(Parameter {
            name: p.name.clone(),
            value,
            range,
            spacing,
        })
    }
}

impl RawReaction {
    fn build(
        &self,
        k: usize,
        species: &[Species],
        parameters: &[Parameter],
        bad: Bad<'_>,
    ) -> Result<Reaction, NetworkError> {
        let r = self;
        let species_index = |name: &str| species.iter().position(|s| s.name == name);
        let rname = r
            .name
            .clone()
            .unwrap_or_else(|| format!("reaction {}", k + 1));
        let mut change = vec![0; species.len()];
        for (name, &c) in &r.change {
            let i = species_index(name)
                .ok_or_else(|| bad(format!("{rname}: change of unknown species {name:?}")))?;
            change[i] = c;
        }
        let mut constant = 1.0;
        let mut params = Vec::new();
        for v in &r.rate {
            match v {
                toml::Value::Float(x) => constant *= x,
                toml::Value::Integer(x) => constant *= *x as f64,
                toml::Value::String(name) => {
                    let q = parameters
                        .iter()
                        .position(|p: &Parameter| &p.name == name)
                        .ok_or_else(|| {
                            bad(format!("{rname}: rate uses unknown parameter {name:?}"))
                        })?;
                    params.push(q);
                }
                other => {
                    return Err(bad(format!(
                        "{rname}: rate entry {other}: expected a number or a parameter name"
                    )));
                }
            }
        }
        if !(constant.is_finite() && constant >= 0.0) {
            return Err(bad(format!(
                "{rname}: rate constant {constant}: expected a finite value ≥ 0"
            )));
        }
        let mut factors: Vec<(usize, Factor)> = Vec::new();
        for f in &r.factors {
            factors.push(f.build(&rname, &species_index, bad)?);
        }
        Ok(Reaction {
            name: rname,
            change,
            constant,
            params,
            factors,
        })
    }
}

impl RawFactor {
    /// The factor and the index of its species (by `species_index`).
    fn build(
        &self,
        rname: &str,
        species_index: &dyn Fn(&str) -> Option<usize>,
        bad: Bad<'_>,
    ) -> Result<(usize, Factor), NetworkError> {
        let f = self;
        let name = match &f.species {
            toml::Value::String(s) => s.clone(),
            toml::Value::Array(list) => {
                return Err(bad(format!(
                    "{rname}: a propensity factor of several species ({}) is not separable; \
                     write the propensity as a product of one-species factors",
                    list.iter()
                        .map(|v| v.to_string())
                        .collect::<Vec<_>>()
                        .join(", ")
                )));
            }
            other => {
                return Err(bad(format!(
                    "{rname}: factor species {other}: expected a species name"
                )));
            }
        };
        let i = species_index(&name)
            .ok_or_else(|| bad(format!("{rname}: factor of unknown species {name:?}")))?;
        let need = |v: Option<f64>, what: &str| -> Result<f64, NetworkError> {
            match v {
                Some(x) if x.is_finite() && x > 0.0 => Ok(x),
                Some(x) => Err(bad(format!(
                    "{rname}: {what} = {x}: expected a finite value > 0"
                ))),
                None => Err(bad(format!("{rname}: factor {} needs {what}", f.kind))),
            }
        };
        let factor = match f.kind.as_str() {
            "linear" => Factor::Linear,
            "binomial" => match f.k {
                Some(k) if (1..=64).contains(&k) => Factor::Binomial { k: k as u32 },
                Some(k) => {
                    return Err(bad(format!(
                        "{rname}: binomial k = {k}: expected an order in 1..=64"
                    )));
                }
                None => return Err(bad(format!("{rname}: factor binomial needs k"))),
            },
            "affine" => {
                let finite = |v: Option<f64>, what: &str| match v {
                    Some(x) if x.is_finite() => Ok(x),
                    Some(x) => Err(bad(format!(
                        "{rname}: {what} = {x}: expected a finite value"
                    ))),
                    None => Err(bad(format!("{rname}: factor affine needs {what}"))),
                };
                Factor::Affine {
                    offset: finite(f.offset, "offset")?,
                    slope: finite(f.slope, "slope")?,
                }
            }
            "hill_repression" => Factor::HillRepression {
                beta: need(f.beta, "beta")?,
                gamma: need(f.gamma, "gamma")?,
                n: f.n.map_or(Ok(1.0), |n| need(Some(n), "n"))?,
            },
            "saturation" => Factor::Saturation {
                beta: need(f.beta, "beta")?,
                gamma: need(f.gamma, "gamma")?,
            },
            "hill_activation" => Factor::HillActivation {
                beta: need(f.beta, "beta")?,
                gamma: need(f.gamma, "gamma")?,
                n: f.n.map_or(Ok(1.0), |n| need(Some(n), "n"))?,
            },
            other => {
                return Err(bad(format!(
                    "{rname}: factor kind {other:?}: expected linear, binomial, affine, hill_repression, saturation or hill_activation"
                )));
            }
        };
        Ok((i, factor))
    }
}

/// The λ-phage toggle switch (paper eq. 6).
pub const TOGGLE: &str = include_str!("../../../assets/networks/toggle.toml");
/// The two-gene cascade with unknown degradation rate (paper eq. 7).
pub const CASCADE: &str = include_str!("../../../assets/networks/cascade.toml");

/// The signaling cascade with `d` species: 0 → S1 at 0.7; S_{i−1} → S_{i−1} + S_i at
/// `z_{i−1}/(5 + z_{i−1})`; each S_i degraded at 0.07 z_i; 64 states per species.
pub fn signaling_cascade(d: usize) -> String {
    let mut s = format!("name = \"signaling-cascade-{d}\"\n");
    for i in 1..=d {
        s += &format!("\n[[species]]\nname = \"S{i}\"\nmax = 64\ninitial = 0\n");
    }
    s += "\n[[reactions]]\nname = \"S1 birth\"\nchange = { S1 = 1 }\nrate = [0.7]\n";
    for i in 2..=d {
        // z/(5 + z) = saturation with β = 1, γ = 5.
        s += &format!(
            "\n[[reactions]]\nname = \"S{i} production\"\nchange = {{ S{i} = 1 }}\nrate = [1.0]\n\
             factors = [{{ species = \"S{p}\", kind = \"saturation\", beta = 1.0, gamma = 5.0 }}]\n",
            p = i - 1
        );
    }
    for i in 1..=d {
        s += &format!(
            "\n[[reactions]]\nname = \"S{i} degradation\"\nchange = {{ S{i} = -1 }}\nrate = [0.07]\n\
             factors = [{{ species = \"S{i}\", kind = \"linear\" }}]\n"
        );
    }
    s
}
