//! palpa-app: the interactive palpation app (the `palpa` command line is the binary's
//! own module tree, `src/cli/`, so the mobile `cdylib` never compiles it).
//!
//! Platform entry points stay thin: `main.rs` parses and dispatches, [`platform`] holds
//! `android_main`; everything else is plain library code that a test can call.
//!
//! - [`render`]: wgpu rendering of a scene into any texture view (window or offscreen),
//!   GPU deformation by compute shader;
//! - [`force`]: the 1 kHz force thread and the [`force::HapticDevice`] it drives;
//! - [`latest`]: the lock-free latest-value cell between the threads;
//! - [`camera`], [`pick`], [`input`]: the orbit camera, picking, and the mapping from
//!   mouse, touch and gamepad events to probe and camera states;
//! - [`session`]: one palpation session (scene, controls, force loop, frame statistics)
//!   shared by the window and the headless mode;
//! - [`ui`]: the egui panels; [`window`]: winit and the surface lifecycle;
//!   [`offscreen`]: headless frames rendered offscreen with a scripted probe.

pub mod camera;
pub mod force;
pub mod gamepad;
pub mod input;
pub mod latest;
pub mod layout;
pub mod network;
pub mod offscreen;
pub mod overlay;
pub mod pick;
pub mod platform;
pub mod priority;
pub mod render;
pub mod scenes;
pub mod session;
pub mod shell;
pub mod stats;
pub mod swapchain;
pub mod ui;
pub mod window;
