//! The GPU context: instance, adapter, device and queue, with errors that say what to do.

use std::sync::Arc;

use anyhow::{Context, anyhow};
use serde::Serialize;

use super::health::GpuHealth;

/// What adapter we got, for reports.
#[derive(Debug, Clone, Serialize)]
pub struct AdapterReport {
    pub name: String,
    pub backend: String,
    pub device_type: String,
}

/// Instance, adapter, device and queue.
#[derive(Debug)]
pub struct Gpu {
    pub instance: wgpu::Instance,
    pub adapter: wgpu::Adapter,
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    /// Errors and loss the device reported (instead of wgpu's default panic).
    pub health: Arc<GpuHealth>,
}

pub const NO_ADAPTER_HELP: &str = "no GPU adapter found. palpa renders on any Vulkan, Metal, \
     DX12 or GL device; without a GPU, install Mesa's software Vulkan driver \
     (Debian: `apt-get install mesa-vulkan-drivers libvulkan1`, or run scripts/deps.sh --gpu) \
     and try again, or select a backend with WGPU_BACKEND=vulkan|gl";

impl Gpu {
    /// Submits `encoder` and waits until the GPU has finished it (headless frames are
    /// timed to completion); an error the device reported meanwhile is returned.
    pub fn submit_and_wait(&self, encoder: wgpu::CommandEncoder) -> anyhow::Result<()> {
        self.queue.submit([encoder.finish()]);
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| anyhow::anyhow!("waiting for the GPU: {e}"))?;
        match self.health.take_message() {
            Some(m) => Err(anyhow!(m)),
            None => Ok(()),
        }
    }

    /// Whether a texture can be viewed in another format than its own (its sRGB twin):
    /// not on GL (`DownlevelFlags::VIEW_FORMATS`). Without it the interface draws into
    /// the sRGB target itself (egui blends in linear space there: a shade lighter edges).
    pub fn can_reinterpret(&self) -> bool {
        self.adapter
            .get_downlevel_capabilities()
            .flags
            .contains(wgpu::DownlevelFlags::VIEW_FORMATS)
    }

    /// A context without a window (tests, `palpa headless`). Honours `WGPU_BACKEND`,
    /// `WGPU_ADAPTER_NAME` and `WGPU_POWER_PREF`.
    pub fn headless() -> anyhow::Result<Self> {
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        Self::with_instance(instance, None)
    }

    /// A context without a window on the given backends only (tests pin Vulkan so
    /// reference images are reproducible).
    pub fn headless_on(backends: wgpu::Backends) -> anyhow::Result<Self> {
        let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
        desc.backends = backends;
        Self::with_instance(wgpu::Instance::new(desc), None)
    }

    /// A context able to present to `surface`.
    pub fn with_instance(
        instance: wgpu::Instance,
        surface: Option<&wgpu::Surface<'_>>,
    ) -> anyhow::Result<Self> {
        let adapter = pollster::block_on(wgpu::util::initialize_adapter_from_env_or_default(
            &instance, surface,
        ))
        .map_err(|e| anyhow!("{NO_ADAPTER_HELP} ({e})"))?;
        let limits = adapter.limits();
        if limits.max_storage_buffers_per_shader_stage < super::deform::STORAGE_BUFFERS {
            anyhow::bail!(
                "the adapter {:?} offers {} storage buffers per shader stage; the GPU \
                 deformation needs {}",
                adapter.get_info().name,
                limits.max_storage_buffers_per_shader_stage,
                super::deform::STORAGE_BUFFERS
            );
        }
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("palpa"),
            required_limits: limits,
            ..Default::default()
        }))
        .with_context(|| format!("the adapter {:?} refused a device", adapter.get_info().name))?;
        let health = Arc::new(GpuHealth::default());
        let h = Arc::clone(&health);
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| h.record_error(&e)));
        let h = Arc::clone(&health);
        device.set_device_lost_callback(move |reason, message| h.record_lost(reason, &message));
        Ok(Gpu {
            instance,
            adapter,
            device,
            queue,
            health,
        })
    }

    /// Whether the adapter rasterizes on the CPU (Mesa's lavapipe, WARP, SwiftShader):
    /// there every blended pixel costs, and the interface leaves out what is only looks.
    pub fn is_software(&self) -> bool {
        self.adapter.get_info().device_type == wgpu::DeviceType::Cpu
    }

    pub fn report(&self) -> AdapterReport {
        let info = self.adapter.get_info();
        AdapterReport {
            name: info.name,
            backend: format!("{:?}", info.backend).to_lowercase(),
            device_type: format!("{:?}", info.device_type).to_lowercase(),
        }
    }
}
