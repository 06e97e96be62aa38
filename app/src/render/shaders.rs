//! The WGSL sources, assembled (the shared `frame.wgsl` and `ramp.wgsl` prepended where
//! used), and their validation by naga in `cargo test`.

const FRAME: &str = include_str!("../../../shaders/frame.wgsl");
const RAMP: &str = include_str!("../../../shaders/ramp.wgsl");

/// A shader of `shaders/`, by file stem.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Shader {
    Deform,
    Embed,
    Surface,
    Ground,
    Solid,
    Landscape,
}

impl Shader {
    pub const ALL: [Shader; 6] = [
        Shader::Deform,
        Shader::Embed,
        Shader::Surface,
        Shader::Ground,
        Shader::Solid,
        Shader::Landscape,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Shader::Deform => "deform.wgsl",
            Shader::Embed => "embed.wgsl",
            Shader::Surface => "surface.wgsl",
            Shader::Ground => "ground.wgsl",
            Shader::Solid => "solid.wgsl",
            Shader::Landscape => "landscape.wgsl",
        }
    }

    /// The complete WGSL source.
    pub fn source(self) -> String {
        match self {
            Shader::Deform => include_str!("../../../shaders/deform.wgsl").to_string(),
            Shader::Embed => include_str!("../../../shaders/embed.wgsl").to_string(),
            Shader::Surface => format!(
                "{FRAME}\n{RAMP}\n{}",
                include_str!("../../../shaders/surface.wgsl")
            ),
            Shader::Ground => format!("{FRAME}\n{}", include_str!("../../../shaders/ground.wgsl")),
            Shader::Solid => format!("{FRAME}\n{}", include_str!("../../../shaders/solid.wgsl")),
            Shader::Landscape => {
                format!(
                    "{RAMP}\n{}",
                    include_str!("../../../shaders/landscape.wgsl")
                )
            }
        }
    }

    pub fn module(self, device: &wgpu::Device) -> wgpu::ShaderModule {
        device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(self.name()),
            source: wgpu::ShaderSource::Wgsl(self.source().into()),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_shader_parses_and_validates() {
        // Every file in shaders/ must be one of ours (a new file must be added to Shader).
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shaders");
        let mut on_disk: Vec<String> = std::fs::read_dir(&dir)
            .expect("shaders/ exists")
            .filter_map(|e| e.ok()?.file_name().into_string().ok())
            .filter(|n| n.ends_with(".wgsl") && n != "frame.wgsl" && n != "ramp.wgsl")
            .collect();
        on_disk.sort();
        let mut known: Vec<String> = Shader::ALL.iter().map(|s| s.name().to_string()).collect();
        known.sort();
        assert_eq!(on_disk, known, "shaders/ and Shader::ALL disagree");

        for s in Shader::ALL {
            let module = naga::front::wgsl::parse_str(&s.source())
                .unwrap_or_else(|e| panic!("{}: {}", s.name(), e.emit_to_string(&s.source())));
            naga::valid::Validator::new(
                naga::valid::ValidationFlags::all(),
                naga::valid::Capabilities::default(),
            )
            .validate(&module)
            .unwrap_or_else(|e| panic!("{}: {e:?}", s.name()));
        }
    }
}
