//! The hyperelastic tissue: the nonlinear vademecum of a palpation scene, what the organ's
//! surface does and what force the tool feels under a press of any depth `d` at any
//! palpable point `s`, beyond the linear answer. Read top-down, in the order a build
//! runs and the app uses it:
//!
//! 1. **Press** ([`options`]: what a build is asked; [`press`], [`presser`],
//!    [`presslog`]): one press at a surface point,
//!    followed to equilibrium on the depth grid by the depth series and Newton
//!    (`crate::fe::path`); the build's presses run two at a time and each is logged as
//!    it finishes, so a killed build goes on from the last one.
//! 2. **Stages** ([`surface`]: the build's driver, [`SurfaceLaw`]): every palpable
//!    vertex and edge midpoint pressed, then, where the quadratic blend between them is
//!    too coarse, triangles split ([`refine`]: where and which points;
//!    [`refine_file`]: a built file split in place; [`refine_plan`]: the cost without
//!    pressing), split triangles' quarters split again ([`subsplit`],
//!    [`subsplit_file`]), and last the band next to the fixed region pressed ([`band`],
//!    [`band_file`]).
//! 3. **Compress** ([`knobs`], [`shapes`], [`predict`], [`weights`]): each press's
//!    residuals over the depths by its SVD to a bound, the shapes in 16 or 8 bits coded
//!    as what their neighbours do not predict, the weights in halves; the knobs a scene
//!    turns (modes, bits, depth step).
//! 4. **File** ([`law`]: [`TissueLaw`], the `.tissue` format, and [`accuracy`]: what
//!    `palpa tissue check --record` measured of it, kept in the file). [`recipe`]: a
//!    whole build as one value, the stages it runs and how it compresses (what `palpa
//!    tissue build --recipe` runs, the shipped file's among them).
//! 5. **On-line** ([`bound`]: [`BoundTissue`], the law bound to one scene's rows, what
//!    the 1 kHz force loop and the 25 Hz surface evaluate, allocation-free;
//!    [`surplus`]: how far the blend may be from the tissue where the probe is;
//!    [`online`]: [`online::Tissue`], the scene's nonlinear model as the loops ask it).

pub mod options;
pub mod press;
pub mod presser;
pub mod presslog;

pub mod surface;

pub mod band;
pub mod band_file;
pub mod refine;
pub mod refine_file;
pub mod refine_plan;
pub mod subsplit;
pub mod subsplit_file;

pub mod knobs;
pub mod predict;
pub mod shapes;
pub mod weights;

pub mod accuracy;
pub mod law;
pub mod recipe;

pub mod bound;
pub mod online;
pub mod surplus;

pub use bound::BoundTissue;
pub use law::TissueLaw;
pub use surface::SurfaceLaw;
