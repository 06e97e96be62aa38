//! SBML import: a reaction network from an SBML Level 2 or 3 core model.
//!
//! What is read, and the conventions (`docs/methods.md` §3c):
//! - **Species.** The initial amount is `initialAmount`, or `initialConcentration ×`
//!   the compartment's size; it must be a whole number of molecules. Where a species'
//!   symbol appears in a kinetic law it stands for its amount when
//!   `hasOnlySubstanceUnits` is true and for `amount / size` otherwise (SBML's rule).
//!   Boundary and constant species, and species no reaction changes, never change:
//!   they are constants of the laws, not coordinates of the state.
//! - **Kinetic laws** are read as the propensity in molecules per unit time, the
//!   discrete stochastic reading the DSMTS uses. A law is accepted when it is a product
//!   of constants, parameters and one-species factors (with quotients and integer
//!   powers): each species' part is rewritten as factors of [`Factor`] —
//!   `z`, `max(0, a + b z)`, `β/(β + γ zⁿ)` — and `z (z−1) ··· (z−k+1)/k!` becomes
//!   one `binomial` factor. Sums across species, functions of a species other than
//!   these, time, delays and piecewise laws are refused naming the reaction.
//! - **Parameters** (global, and local ones shadowing them) that multiply a law to the
//!   first power stay named parameters of the network (a TOML range can then make them
//!   coordinates); elsewhere (a Hill constant, a power) their value is folded in.
//! - **Refused** with the element named: events, rules, initial assignments,
//!   constraints, function definitions, reversible or fast reactions, stoichiometry
//!   given by math or not a whole number.
//!
//! Every box is automatic (`max = "auto"`): SBML carries no truncation.

use std::collections::{BTreeMap, BTreeSet, HashMap};

use roxmltree::{Document, Node};

use super::network::{
    Factor, MAX_INITIAL, Network, NetworkError, Parameter, Reaction, Spacing, Species,
};

/// The reader that tells a network file's two formats apart lives with the one that
/// needs telling apart (an SBML document), so `network` knows only its own TOML.
impl Network {
    /// A network file's text, SBML or TOML by its content.
    pub fn from_text(text: &str, source_name: &str) -> Result<Self, NetworkError> {
        if looks_like_sbml(text) {
            from_sbml(text, source_name)
        } else if text.trim_start().starts_with('<') {
            // XML but not SBML: a TOML parser's complaint about `<` would mislead.
            Err(NetworkError::Invalid {
                source_name: source_name.to_string(),
                what: "an XML document whose root is not <sbml>: expected an SBML model or \
                       a TOML network"
                    .to_string(),
            })
        } else {
            Self::from_toml(text, source_name)
        }
    }
}

/// Whether `text` looks like SBML (an XML document whose root is `sbml`).
pub fn looks_like_sbml(text: &str) -> bool {
    let head: String = text.chars().take(4096).collect();
    head.trim_start().starts_with('<') && head.contains("<sbml")
}

/// Reads an SBML document; `source_name` names it in errors.
pub fn from_sbml(text: &str, source_name: &str) -> Result<Network, NetworkError> {
    let bad = |what: String| NetworkError::Invalid {
        source_name: source_name.to_string(),
        what,
    };
    let doc = Document::parse(text).map_err(|e| NetworkError::Syntax {
        source_name: source_name.to_string(),
        message: format!("not well-formed XML: {e}"),
    })?;
    let root = doc.root_element();
    if root.tag_name().name() != "sbml" {
        return Err(bad(format!(
            "the root element is <{}>: expected <sbml>",
            root.tag_name().name()
        )));
    }
    let level = root.attribute("level").unwrap_or("?");
    if !matches!(level, "2" | "3") {
        return Err(bad(format!("SBML level {level}: expected Level 2 or 3")));
    }
    let model = child(root, "model").ok_or_else(|| bad("no <model> element".into()))?;
    for (list, what) in [
        ("listOfEvents", "events"),
        ("listOfRules", "rules"),
        ("listOfInitialAssignments", "initial assignments"),
        ("listOfConstraints", "constraints"),
        ("listOfFunctionDefinitions", "function definitions"),
    ] {
        if let Some(l) = child(model, list)
            && l.children().any(|c| c.is_element())
        {
            let first = l
                .children()
                .find(|c| c.is_element())
                .map_or("", |c| c.tag_name().name());
            return Err(bad(format!(
                "the model has {what} (<{list}>, first <{first}>): not supported; \
                 palpa reads reactions with constant parameters only"
            )));
        }
    }
    let number = |n: Node, attr: &str| -> Result<Option<f64>, NetworkError> {
        match n.attribute(attr) {
            None => Ok(None),
            Some(v) => v.trim().parse::<f64>().map(Some).map_err(|_| {
                bad(format!(
                    "<{} id={:?}> {attr}={v:?}: expected a number",
                    n.tag_name().name(),
                    n.attribute("id").unwrap_or("")
                ))
            }),
        }
    };
    // Compartments: their sizes.
    let mut sizes: HashMap<String, Option<f64>> = HashMap::new();
    for c in elements(model, "listOfCompartments", "compartment") {
        let id = id_of(c, &bad)?;
        let size = match number(c, "size")? {
            Some(s) => Some(s),
            None => number(c, "volume")?,
        };
        // Level 2 gives an unset size the value 1.
        let size = size.or((level == "2").then_some(1.0));
        sizes.insert(id, size);
    }
    // Parameters.
    let mut globals: Vec<(String, f64)> = Vec::new();
    for p in elements(model, "listOfParameters", "parameter") {
        let id = id_of(p, &bad)?;
        let v = number(p, "value")?.ok_or_else(|| bad(format!("parameter {id} has no value")))?;
        globals.push((id, v));
    }
    // Species: amounts, and what their symbol means in a law.
    struct Sp {
        id: String,
        amount: f64,
        /// symbol value = scale · amount
        scale: f64,
        fixed: bool,
    }
    let mut all: Vec<Sp> = Vec::new();
    for s in elements(model, "listOfSpecies", "species") {
        let id = id_of(s, &bad)?;
        let comp = s.attribute("compartment").unwrap_or("");
        let size = sizes.get(comp).copied().flatten();
        let only_substance = s.attribute("hasOnlySubstanceUnits") == Some("true");
        let need_size = |what: &str| {
            size.filter(|v| v.is_finite() && *v > 0.0).ok_or_else(|| {
                bad(format!(
                    "species {id}: {what} needs the size of compartment {comp:?}, which is not \
                     given or not > 0"
                ))
            })
        };
        let amount = match (
            number(s, "initialAmount")?,
            number(s, "initialConcentration")?,
        ) {
            (Some(a), _) => a,
            (None, Some(c)) => c * need_size("an initial concentration")?,
            (None, None) => {
                return Err(bad(format!(
                    "species {id} has no initial amount or concentration"
                )));
            }
        };
        let scale = if only_substance {
            1.0
        } else {
            1.0 / need_size("a symbol in concentration units")?
        };
        let fixed = s.attribute("boundaryCondition") == Some("true")
            || s.attribute("constant") == Some("true");
        all.push(Sp {
            id,
            amount,
            scale,
            fixed,
        });
    }
    // Reactions: stoichiometry first, so that species no reaction changes become constants.
    struct RawReaction<'a, 'b> {
        name: String,
        change: BTreeMap<String, i64>,
        law: Node<'a, 'b>,
        locals: HashMap<String, f64>,
    }
    let mut raw = Vec::new();
    for r in elements(model, "listOfReactions", "reaction") {
        let name = id_of(r, &bad)?;
        if r.attribute("reversible")
            .unwrap_or(if level == "2" { "true" } else { "false" })
            == "true"
        {
            return Err(bad(format!(
                "reaction {name} is reversible: its kinetic law is a net rate, which has no \
                 stochastic reading; write it as two irreversible reactions"
            )));
        }
        if r.attribute("fast") == Some("true") {
            return Err(bad(format!("reaction {name} is fast: not supported")));
        }
        let mut change: BTreeMap<String, i64> = BTreeMap::new();
        for (list, sign) in [("listOfReactants", -1i64), ("listOfProducts", 1)] {
            for sr in elements(r, list, "speciesReference") {
                let sp = sr.attribute("species").unwrap_or("").to_string();
                if child(sr, "stoichiometryMath").is_some() {
                    return Err(bad(format!(
                        "reaction {name}: the stoichiometry of {sp} is given by math: not supported"
                    )));
                }
                let st = number(sr, "stoichiometry")?.unwrap_or(1.0);
                if !(st.is_finite() && st >= 0.0 && st.fract() == 0.0 && st <= 1e6) {
                    return Err(bad(format!(
                        "reaction {name}: stoichiometry {st} of {sp}: expected a whole number \
                         from 0 to 1000000"
                    )));
                }
                *change.entry(sp).or_default() += sign * st as i64;
            }
        }
        let kl = child(r, "kineticLaw")
            .ok_or_else(|| bad(format!("reaction {name} has no kinetic law")))?;
        let law = child(kl, "math")
            .and_then(|m| m.children().find(|c| c.is_element()))
            .ok_or_else(|| bad(format!("reaction {name}: the kinetic law has no <math>")))?;
        let mut locals = HashMap::new();
        for list in ["listOfParameters", "listOfLocalParameters"] {
            for p in kl
                .children()
                .filter(|c| c.tag_name().name() == list)
                .flat_map(|l| l.children().filter(|c| c.is_element()))
            {
                let id = id_of(p, &bad)?;
                let v = number(p, "value")?.ok_or_else(|| {
                    bad(format!(
                        "reaction {name}: local parameter {id} has no value"
                    ))
                })?;
                locals.insert(id, v);
            }
        }
        raw.push(RawReaction {
            name,
            change,
            law,
            locals,
        });
    }
    if raw.is_empty() {
        return Err(bad("the model has no reactions".into()));
    }
    let changed: BTreeSet<&str> = raw
        .iter()
        .flat_map(|r| {
            r.change
                .iter()
                .filter(|(_, c)| **c != 0)
                .map(|(s, _)| s.as_str())
        })
        .collect();
    let mut species = Vec::new();
    let mut fixed = Vec::new();
    let mut symbols: HashMap<String, Symbol> = HashMap::new();
    for s in &all {
        if s.fixed || !changed.contains(s.id.as_str()) {
            symbols.insert(s.id.clone(), Symbol::Value(s.scale * s.amount));
            fixed.push((s.id.clone(), s.amount));
            continue;
        }
        let whole = s.amount.round();
        if !(s.amount.is_finite()
            && s.amount >= 0.0
            && (s.amount - whole).abs() <= 1e-9 * whole.max(1.0))
        {
            return Err(bad(format!(
                "species {}: initial amount {}: expected a whole number of molecules ≥ 0",
                s.id, s.amount
            )));
        }
        if whole > MAX_INITIAL as f64 {
            return Err(bad(format!(
                "species {}: initial amount {}: expected at most {MAX_INITIAL} molecules",
                s.id, s.amount
            )));
        }
        symbols.insert(s.id.clone(), Symbol::Species(species.len(), s.scale));
        species.push(Species {
            name: s.id.clone(),
            max: None,
            initial: whole as usize,
        });
    }
    for (c, size) in &sizes {
        if let Some(v) = size {
            symbols.entry(c.clone()).or_insert(Symbol::Value(*v));
        }
    }
    for (q, (id, _)) in globals.iter().enumerate() {
        symbols.insert(id.clone(), Symbol::Parameter(q));
    }
    let mut reactions = Vec::new();
    let mut used = vec![false; globals.len()];
    for r in &raw {
        let mut change = vec![0i32; species.len()];
        for (sp, c) in &r.change {
            match symbols.get(sp) {
                Some(Symbol::Species(i, _)) => {
                    change[*i] = i32::try_from(*c).map_err(|_| {
                        bad(format!(
                            "reaction {}: change {c} of {sp} is too large",
                            r.name
                        ))
                    })?;
                }
                Some(_) => {} // a boundary or constant species: not part of the state
                None => {
                    return Err(bad(format!(
                        "reaction {} refers to unknown species {sp:?}",
                        r.name
                    )));
                }
            }
        }
        let expr = parse_math(r.law).map_err(|e| bad(format!("reaction {}: {e}", r.name)))?;
        let ctx = Ctx {
            symbols: &symbols,
            locals: &r.locals,
            globals: &globals,
        };
        let prod = ctx
            .product(&expr)
            .map_err(|e| bad(format!("reaction {}: kinetic law: {e}", r.name)))?;
        let (constant, params, factors) = prod
            .into_factors(&globals)
            .map_err(|e| bad(format!("reaction {}: kinetic law: {e}", r.name)))?;
        for &q in &params {
            used[q] = true;
        }
        reactions.push((r.name.clone(), change, constant, params, factors));
    }
    // Keep only the parameters the rates name; renumber.
    let kept: Vec<usize> = (0..globals.len()).filter(|&q| used[q]).collect();
    let parameters = kept
        .iter()
        .map(|&q| Parameter {
            name: globals[q].0.clone(),
            value: globals[q].1,
            range: None,
            spacing: Spacing::Linear,
        })
        .collect();
    let reactions = reactions
        .into_iter()
        .map(|(name, change, constant, params, factors)| Reaction {
            name,
            change,
            constant,
            params: params
                .iter()
                .map(|q| kept.iter().position(|k| k == q).unwrap_or(0))
                .collect(),
            factors,
        })
        .collect();
    let name = model
        .attribute("id")
        .or(model.attribute("name"))
        .unwrap_or(source_name)
        .to_string();
    if species.is_empty() {
        return Err(bad(
            "no reaction changes a species' count (boundary, constant or balanced species \
             are held fixed): there is no chemical master equation to solve"
                .into(),
        ));
    }
    let mut network = Network::from_parts(name, species, parameters, reactions, source_name)?;
    network.fixed = fixed;
    Ok(network)
}

fn child<'a, 'b>(n: Node<'a, 'b>, name: &str) -> Option<Node<'a, 'b>> {
    n.children().find(|c| c.tag_name().name() == name)
}

fn elements<'a, 'b>(
    n: Node<'a, 'b>,
    list: &'static str,
    item: &'static str,
) -> impl Iterator<Item = Node<'a, 'b>> {
    n.children()
        .filter(move |c| c.tag_name().name() == list)
        .flat_map(move |l| l.children().filter(move |c| c.tag_name().name() == item))
}

fn id_of(n: Node, bad: &dyn Fn(String) -> NetworkError) -> Result<String, NetworkError> {
    n.attribute("id")
        .or(n.attribute("name")) // Level 1 style
        .map(str::to_string)
        .ok_or_else(|| bad(format!("a <{}> has no id", n.tag_name().name())))
}

/// What an identifier in a law stands for.
#[derive(Debug, Clone, Copy)]
enum Symbol {
    /// State species `i`; the symbol's value is `scale · z_i`.
    Species(usize, f64),
    /// Global parameter `q` (index into the model's parameters).
    Parameter(usize),
    Value(f64),
}

/// A MathML expression.
#[derive(Debug, Clone, PartialEq)]
enum Expr {
    Num(f64),
    Sym(String),
    /// An operator (MathML element name) applied to its arguments; qualifiers such as
    /// `logbase` and `degree` are arguments `Op("logbase", [x])`.
    Op(String, Vec<Expr>),
}

fn parse_math(n: Node) -> Result<Expr, String> {
    let name = n.tag_name().name();
    let text = || n.text().unwrap_or("").trim().to_string();
    match name {
        "ci" => Ok(Expr::Sym(text())),
        "cn" => {
            let parts: Vec<String> = n
                .children()
                .filter(|c| c.is_text())
                .map(|c| c.text().unwrap_or("").trim().to_string())
                .filter(|t| !t.is_empty())
                .collect();
            let num = |s: &str| {
                s.parse::<f64>()
                    .map_err(|_| format!("<cn> {s:?} is not a number"))
            };
            match (n.attribute("type").unwrap_or("real"), parts.as_slice()) {
                ("e-notation", [m, e]) => Ok(Expr::Num(num(m)? * 10f64.powf(num(e)?))),
                ("rational", [a, b]) => Ok(Expr::Num(num(a)? / num(b)?)),
                (_, [v]) => Ok(Expr::Num(num(v)?)),
                (t, _) => Err(format!("<cn type={t:?}> with {} parts", parts.len())),
            }
        }
        "pi" => Ok(Expr::Num(std::f64::consts::PI)),
        "exponentiale" => Ok(Expr::Num(std::f64::consts::E)),
        "csymbol" => Err(format!(
            "<csymbol> {:?} ({}): laws that depend on time or delays are not supported",
            text(),
            n.attribute("definitionURL").unwrap_or("")
        )),
        "apply" => {
            let mut kids = n.children().filter(|c| c.is_element());
            let op = kids.next().ok_or("an empty <apply>")?;
            let args = kids.map(parse_math).collect::<Result<Vec<_>, _>>()?;
            if op.tag_name().name() == "csymbol" {
                return parse_math(op);
            }
            Ok(Expr::Op(op.tag_name().name().to_string(), args))
        }
        "logbase" | "degree" => {
            let inner = n
                .children()
                .find(|c| c.is_element())
                .ok_or("an empty qualifier")?;
            Ok(Expr::Op(name.to_string(), vec![parse_math(inner)?]))
        }
        "semantics" => {
            let inner = n
                .children()
                .find(|c| c.is_element())
                .ok_or("an empty <semantics>")?;
            parse_math(inner)
        }
        other => Err(format!("MathML <{other}> is not supported")),
    }
}

/// The largest whole power of one species' expression a law may use (a propensity of
/// order 64 is already far beyond chemistry).
const MAX_POWER: u32 = 64;

/// `(a + b zⁿ)^e` of one species.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Atom {
    species: usize,
    a: f64,
    b: f64,
    n: f64,
    e: i32,
}

/// A law in the network's form: constant, named parameters, one-species factors.
type Separable = (f64, Vec<usize>, Vec<(usize, Factor)>);

/// `c · Π params^e · Π atoms`.
#[derive(Debug, Clone, Default)]
struct Prod {
    c: f64,
    params: Vec<(usize, i32)>,
    atoms: Vec<Atom>,
}

impl Prod {
    fn constant(c: f64) -> Self {
        Prod {
            c,
            ..Prod::default()
        }
    }

    fn times(mut self, o: Prod) -> Prod {
        self.c *= o.c;
        self.params.extend(o.params);
        self.atoms.extend(o.atoms);
        self
    }

    fn pow(mut self, k: i32) -> Prod {
        self.c = self.c.powi(k);
        // Saturating: a tower of powers is refused by `into_factors`, not overflowed.
        self.params
            .iter_mut()
            .for_each(|p| p.1 = p.1.saturating_mul(k));
        self.atoms
            .iter_mut()
            .for_each(|a| a.e = a.e.saturating_mul(k));
        self
    }

    /// The network's form: constant, parameters to the first power, factors.
    fn into_factors(self, globals: &[(String, f64)]) -> Result<Separable, String> {
        let mut c = self.c;
        // Parameters: net exponent per parameter; a first power stays named.
        let mut net: BTreeMap<usize, i32> = BTreeMap::new();
        for (q, e) in self.params {
            *net.entry(q).or_default() += e;
        }
        let mut params = Vec::new();
        for (q, e) in net {
            match e {
                0 => {}
                1 => params.push(q),
                e => c *= globals[q].1.powi(e),
            }
        }
        // Atoms: pure powers of z merged per species; the others become factors.
        let mut power: BTreeMap<usize, f64> = BTreeMap::new();
        let mut factors = Vec::new();
        for at in self.atoms {
            if at.e == 0 {
                continue;
            }
            if at.e.unsigned_abs() > MAX_POWER {
                return Err(format!(
                    "a power {} of an expression in a species: at most {MAX_POWER}",
                    at.e
                ));
            }
            if at.a == 0.0 {
                c *= at.b.powi(at.e);
                *power.entry(at.species).or_default() += at.n * f64::from(at.e);
            } else if at.b == 0.0 {
                c *= at.a.powi(at.e);
            } else if at.e > 0 {
                if at.n != 1.0 {
                    return Err(format!(
                        "{} + {}·z^{} in a numerator: only first powers in sums are supported",
                        at.a, at.b, at.n
                    ));
                }
                for _ in 0..at.e {
                    factors.push((
                        at.species,
                        Factor::Affine {
                            offset: at.a,
                            slope: at.b,
                        },
                    ));
                }
            } else {
                if !(at.a > 0.0 && at.b > 0.0 && at.n > 0.0) {
                    return Err(format!(
                        "a denominator {} + {}·z^{} that can vanish or turn negative",
                        at.a, at.b, at.n
                    ));
                }
                for _ in 0..-at.e {
                    c /= at.a;
                    factors.push((
                        at.species,
                        Factor::HillRepression {
                            beta: at.a,
                            gamma: at.b,
                            n: at.n,
                        },
                    ));
                }
            }
        }
        for (i, m) in power {
            if m > f64::from(MAX_POWER) {
                return Err(format!("a power z^{m} of a species: at most z^{MAX_POWER}"));
            }
            if m < 0.0 || m.fract() != 0.0 {
                return Err(format!(
                    "a power z^{m} of a species: expected a whole power ≥ 0 (the law must stay \
                     finite at z = 0)"
                ));
            }
            for _ in 0..m as usize {
                factors.push((i, Factor::Linear));
            }
        }
        merge_binomials(&mut factors, &mut c);
        if !(c.is_finite() && c >= 0.0) {
            return Err(format!(
                "its constant part is {c}: expected a finite value ≥ 0 (a propensity)"
            ));
        }
        Ok((c, params, factors))
    }
}

/// Rewrites `z (z−1) ··· (z−k+1)` among a species' factors as `k! · binomial(k)`.
fn merge_binomials(factors: &mut Vec<(usize, Factor)>, c: &mut f64) {
    let species: BTreeSet<usize> = factors.iter().map(|f| f.0).collect();
    for i in species {
        loop {
            let has = |f: &[(usize, Factor)], j: u32| {
                f.iter().position(|&(s, g)| {
                    s == i
                        && match g {
                            Factor::Linear => j == 0,
                            Factor::Affine { offset, slope } => {
                                slope == 1.0 && offset == -f64::from(j)
                            }
                            _ => false,
                        }
                })
            };
            let mut k = 0u32;
            while has(factors, k).is_some() && k < 64 {
                k += 1;
            }
            if k < 2 {
                break;
            }
            for j in 0..k {
                if let Some(p) = has(factors, j) {
                    factors.remove(p);
                }
            }
            *c *= (1..=k).map(f64::from).product::<f64>();
            factors.push((i, Factor::Binomial { k }));
        }
    }
}

struct Ctx<'a> {
    symbols: &'a HashMap<String, Symbol>,
    locals: &'a HashMap<String, f64>,
    globals: &'a [(String, f64)],
}

impl Ctx<'_> {
    fn lookup(&self, name: &str) -> Result<Symbol, String> {
        if let Some(v) = self.locals.get(name) {
            return Ok(Symbol::Value(*v));
        }
        self.symbols
            .get(name)
            .copied()
            .ok_or_else(|| format!("unknown identifier {name:?}"))
    }

    /// The species an expression depends on.
    fn species(&self, e: &Expr, out: &mut BTreeSet<usize>) -> Result<(), String> {
        match e {
            Expr::Num(_) => Ok(()),
            Expr::Sym(s) => {
                if let Symbol::Species(i, _) = self.lookup(s)? {
                    out.insert(i);
                }
                Ok(())
            }
            Expr::Op(_, args) => args.iter().try_for_each(|a| self.species(a, out)),
        }
    }

    fn depends(&self, e: &Expr) -> Result<BTreeSet<usize>, String> {
        let mut s = BTreeSet::new();
        self.species(e, &mut s)?;
        Ok(s)
    }

    /// The value of an expression that names no species.
    fn value(&self, e: &Expr) -> Result<f64, String> {
        let v = match e {
            Expr::Num(x) => *x,
            Expr::Sym(s) => match self.lookup(s)? {
                Symbol::Value(v) => v,
                Symbol::Parameter(q) => self.globals[q].1,
                Symbol::Species(..) => return Err(format!("{s} is a species")),
            },
            Expr::Op(op, args) => {
                let v: Vec<f64> = args
                    .iter()
                    .filter(|a| !matches!(a, Expr::Op(o, _) if o == "logbase" || o == "degree"))
                    .map(|a| self.value(a))
                    .collect::<Result<_, _>>()?;
                let qualifier = |name: &str, default: f64| -> Result<f64, String> {
                    match args
                        .iter()
                        .find(|a| matches!(a, Expr::Op(o, _) if o == name))
                    {
                        Some(Expr::Op(_, q)) => self.value(&q[0]),
                        _ => Ok(default),
                    }
                };
                match (op.as_str(), v.as_slice()) {
                    ("times", _) => v.iter().product(),
                    ("plus", _) => v.iter().sum(),
                    ("minus", [x]) => -x,
                    ("minus", [x, y]) => x - y,
                    ("divide", [x, y]) => x / y,
                    ("power", [x, y]) => x.powf(*y),
                    ("root", [x]) => x.powf(1.0 / qualifier("degree", 2.0)?),
                    ("exp", [x]) => x.exp(),
                    ("ln", [x]) => x.ln(),
                    ("log", [x]) => x.log(qualifier("logbase", 10.0)?),
                    ("abs", [x]) => x.abs(),
                    ("floor", [x]) => x.floor(),
                    ("ceiling", [x]) => x.ceil(),
                    (op, v) => {
                        return Err(format!(
                            "<{op}> with {} arguments is not supported",
                            v.len()
                        ));
                    }
                }
            }
        };
        Ok(v)
    }

    /// The law as a product of constants, parameters and one-species atoms.
    fn product(&self, e: &Expr) -> Result<Prod, String> {
        let deps = self.depends(e)?;
        match e {
            Expr::Sym(s) => {
                return Ok(match self.lookup(s)? {
                    Symbol::Species(i, scale) => Prod {
                        c: 1.0,
                        params: vec![],
                        atoms: vec![Atom {
                            species: i,
                            a: 0.0,
                            b: scale,
                            n: 1.0,
                            e: 1,
                        }],
                    },
                    Symbol::Parameter(q) => Prod {
                        c: 1.0,
                        params: vec![(q, 1)],
                        atoms: vec![],
                    },
                    Symbol::Value(v) => Prod::constant(v),
                });
            }
            Expr::Num(x) => return Ok(Prod::constant(*x)),
            // Without species, only products keep parameters named; the rest is a number.
            Expr::Op(op, args)
                if deps.is_empty()
                    && !(matches!(op.as_str(), "times" | "divide" | "power")
                        || (op == "minus" && args.len() == 1)) =>
            {
                return Ok(Prod::constant(self.value(e)?));
            }
            Expr::Op(..) => {}
        }
        let Expr::Op(op, args) = e else {
            unreachable!("numbers and symbols returned above")
        };
        match (op.as_str(), args.as_slice()) {
            ("times", _) => args
                .iter()
                .try_fold(Prod::constant(1.0), |p, a| Ok(p.times(self.product(a)?))),
            ("divide", [x, y]) => {
                let den = self.product(y)?;
                if den.c == 0.0 {
                    return Err("a division by zero".into());
                }
                Ok(self.product(x)?.times(den.pow(-1)))
            }
            ("minus", [x]) => {
                let mut p = self.product(x)?;
                p.c = -p.c;
                Ok(p)
            }
            ("power", [x, y]) => {
                if !self.depends(y)?.is_empty() {
                    return Err("a power whose exponent depends on a species".into());
                }
                let k = self.value(y)?;
                let base = self.product(x)?;
                if k.fract() == 0.0 && k.abs() <= 64.0 {
                    return Ok(base.pow(k as i32));
                }
                match base.atoms.as_slice() {
                    [at] if at.a == 0.0 && at.e == 1 && base.params.is_empty() && base.c > 0.0 => {
                        Ok(Prod {
                            c: base.c.powf(k),
                            params: vec![],
                            atoms: vec![Atom {
                                b: at.b.powf(k),
                                n: at.n * k,
                                ..*at
                            }],
                        })
                    }
                    _ => Err(format!(
                        "a non-whole power {k} of an expression in a species"
                    )),
                }
            }
            ("plus" | "minus", _) => self.sum(e, &deps),
            (op, _) => Err(format!(
                "<{op}> of a species is not a separable propensity factor"
            )),
        }
    }

    /// A sum in one species: `a + b zⁿ` (every non-constant term the same power).
    fn sum(&self, e: &Expr, deps: &BTreeSet<usize>) -> Result<Prod, String> {
        if deps.len() > 1 {
            return Err(
                "a sum of terms in several species is not separable (a propensity must be a \
                 product of one-species factors)"
                    .into(),
            );
        }
        let mut terms = Vec::new();
        flatten_sum(e, 1.0, &mut terms);
        let (mut a, mut b, mut n) = (0.0, 0.0, None::<f64>);
        for (sign, t) in terms {
            if self.depends(t)?.is_empty() {
                a += sign * self.value(t)?;
                continue;
            }
            let p = self.product(t)?;
            let value_of_params: f64 = p
                .params
                .iter()
                .map(|&(q, e)| self.globals[q].1.powi(e))
                .product();
            match p.atoms.as_slice() {
                // (b zⁿ)^e = bᵉ z^{n e}
                [at] if at.a == 0.0 && at.e != 0 => {
                    let power = at.n * f64::from(at.e);
                    if n.is_some_and(|m| m != power) {
                        return Err("a sum of different powers of a species".into());
                    }
                    n = Some(power);
                    b += sign * p.c * value_of_params * at.b.powi(at.e);
                }
                _ => {
                    return Err(
                        "a sum whose terms are not multiples of one power of a species".into(),
                    );
                }
            }
        }
        let species = *deps.iter().next().ok_or("an empty sum")?;
        Ok(Prod {
            c: 1.0,
            params: vec![],
            atoms: vec![Atom {
                species,
                a,
                b,
                n: n.unwrap_or(1.0),
                e: 1,
            }],
        })
    }
}

/// The terms of nested `plus`/`minus` with their signs.
fn flatten_sum<'e>(e: &'e Expr, sign: f64, out: &mut Vec<(f64, &'e Expr)>) {
    match e {
        Expr::Op(op, args) if op == "plus" => args.iter().for_each(|a| flatten_sum(a, sign, out)),
        Expr::Op(op, args) if op == "minus" && args.len() == 2 => {
            flatten_sum(&args[0], sign, out);
            flatten_sum(&args[1], -sign, out);
        }
        Expr::Op(op, args) if op == "minus" && args.len() == 1 => flatten_sum(&args[0], -sign, out),
        _ => out.push((sign, e)),
    }
}
