//! Opening a network that has no meta-model yet: the off-line build (the tensor-train
//! solver with its defaults, as `palpa cme offline`) in a named background thread with
//! progress and cancel, saved atomically to a cache keyed by the network's content and
//! the solver options, so the next open is immediate.

use std::path::{Path, PathBuf};

use palpa_core::cme::build;
use palpa_core::cme::network::Network;
use palpa_core::cme::{sizing, ttsolve};

use super::job::{Job, JobState};

/// Where a network's meta-model is cached: next to its TOML file, or for a built-in
/// network in the user's cache folder (`$XDG_CACHE_HOME/palpa`, `~/.cache/palpa`, else
/// the temporary folder). The name carries a hash of the network and the options.
pub fn cache_path(network: &Network, recipe: &build::Recipe, toml: Option<&Path>) -> PathBuf {
    let hash = recipe.hash(network);
    match toml {
        Some(p) => {
            let stem = p.file_stem().map_or_else(
                || "network".to_string(),
                |s| s.to_string_lossy().into_owned(),
            );
            p.with_file_name(format!("{stem}.{hash:016x}.palpa"))
        }
        None => {
            let base = std::env::var_os("XDG_CACHE_HOME")
                .map(PathBuf::from)
                .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))
                .unwrap_or_else(std::env::temp_dir);
            base.join("palpa")
                .join(format!("{}.{hash:016x}.palpa", network.name))
        }
    }
}

/// Where a build stands (done: the saved file).
pub type BuildState = JobState<PathBuf>;

/// A network's off-line build running in the background.
#[derive(Debug)]
pub struct NetworkBuild {
    pub network: Network,
    pub out: PathBuf,
    pub job: Job<PathBuf>,
}

impl NetworkBuild {
    /// Starts building `network`'s meta-model into `out`.
    pub fn start(network: Network, recipe: build::Recipe, out: PathBuf) -> anyhow::Result<Self> {
        let (net, path) = (network.clone(), out.clone());
        let job = Job::start("palpa-network-build", move |ctx| {
            let t_end = recipe.options.t_end;
            // Automatic boxes (an SBML network's) are sized here, off the frame thread.
            let (net, _) = sizing::with_boxes(&net, t_end).map_err(|e| e.to_string())?;
            let mut progress = |s: ttsolve::Step| ctx.progress(s.t / t_end);
            let built = recipe
                .build(&net, Some(ctx.flag()), &mut progress)
                .map_err(|e| e.to_string())?;
            if let Some(dir) = path.parent() {
                std::fs::create_dir_all(dir)
                    .map_err(|e| format!("creating {}: {e}", dir.display()))?;
            }
            built
                .save(&net, &path)
                .map_err(|e| format!("saving {}: {e}", path.display()))?;
            Ok(path)
        })?;
        Ok(NetworkBuild { network, out, job })
    }

    /// Takes what the thread sent since the last call (call once per frame).
    pub fn poll(&mut self) -> &BuildState {
        self.job.poll()
    }

    /// The room of the built model at `path` (the network kept for the checks).
    pub fn room(&self, path: &Path) -> anyhow::Result<super::NetworkRoom> {
        let mut room = super::open(path)?;
        room.network = Some(self.network.clone());
        Ok(room)
    }

    /// Tells the build to stop at its next step (it is not waited for).
    pub fn cancel(&mut self) {
        self.job.cancel();
    }
}

/// Shows a build in progress: its network, a progress bar, cancel. Returns whether
/// cancel was pressed.
pub fn show(ctx: &egui::Context, b: &NetworkBuild, hud: &mut crate::ui::Hud) -> bool {
    let mut cancel = false;
    egui::Window::new("building the network's meta-model")
        .default_pos([12.0, 12.0])
        .resizable(false)
        .show(ctx, |ui| {
            ui.label(format!(
                "{}: {} species, {} parameters",
                b.network.name,
                b.network.species.len(),
                b.network.parameters.len()
            ));
            ui.label(egui::RichText::new(format!("into {}", b.out.display())).small());
            match &b.job.state {
                BuildState::Running { progress } => {
                    ui.add(
                        egui::ProgressBar::new(*progress as f32)
                            .show_percentage()
                            .text("off-line solve (tensor train, BDF2)"),
                    );
                    cancel = ui.button("cancel").clicked();
                }
                BuildState::Done(p) => {
                    ui.label(format!("built: {}", p.display()));
                }
                BuildState::Failed(why) => {
                    ui.colored_label(egui::Color32::from_rgb(230, 90, 80), why);
                }
                BuildState::Cancelled => {
                    ui.label("cancelled: nothing was saved");
                }
            }
            if let Some(m) = &hud.message {
                ui.colored_label(egui::Color32::from_rgb(230, 160, 60), m);
            }
            ui.separator();
            crate::ui::scene_switcher(ui, hud);
        });
    cancel
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::{Duration, Instant};

    #[test]
    fn the_cache_is_keyed_by_network_and_options() {
        let n = Network::built_in("toggle").expect("built in");
        let o = build::Recipe::default_for(&n, 300.0);
        let toml = Path::new("/some/where/my.toml");
        let p = cache_path(&n, &o, Some(toml));
        assert_eq!(p.parent(), Some(Path::new("/some/where")));
        assert!(
            p.file_name()
                .is_some_and(|f| f.to_string_lossy().starts_with("my."))
        );
        let other = build::Recipe {
            options: ttsolve::Options {
                eps: o.options.eps / 10.0,
                ..o.options
            },
            views: None,
        };
        assert_ne!(cache_path(&n, &other, Some(toml)), p);
        let c = Network::built_in("cascade").expect("built in");
        assert_ne!(cache_path(&c, &o, Some(toml)), p);
    }

    /// A cancelled build stops at its next step and saves nothing.
    #[test]
    fn a_cancelled_build_saves_nothing() {
        let dir = tempfile::tempdir().expect("tempdir");
        let out = dir.path().join("cascade.palpa");
        let n = Network::built_in("cascade").expect("built in");
        let recipe = build::Recipe::default_for(&n, 300.0);
        let mut b = NetworkBuild::start(n, recipe, out.clone()).expect("starts");
        std::thread::sleep(Duration::from_millis(50));
        b.cancel();
        assert_eq!(*b.poll(), BuildState::Cancelled);
        let t0 = Instant::now();
        while b.job.thread_alive() && t0.elapsed() < Duration::from_secs(60) {
            std::thread::sleep(Duration::from_millis(5));
        }
        assert!(!b.job.thread_alive(), "the build thread ended");
        assert!(!out.exists(), "nothing saved");
    }
}
