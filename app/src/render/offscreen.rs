//! Offscreen targets: a colour texture to render into, read back as RGBA8, saved as PNG.

use std::path::Path;

use anyhow::{Context, anyhow};

/// The offscreen colour format (sRGB, so images match what a window shows).
pub const FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;
/// The same texture seen without sRGB encoding, for egui (which blends in gamma space).
pub const UI_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;

/// A colour texture of a fixed size and a buffer to read it back.
#[derive(Debug)]
pub struct Offscreen {
    pub texture: wgpu::Texture,
    pub view: wgpu::TextureView,
    /// A view of the same texture for the egui overlay, in `ui_format`.
    pub ui_view: wgpu::TextureView,
    /// [`UI_FORMAT`], or [`FORMAT`] itself where the device cannot view a texture in
    /// another format ([`Gpu::can_reinterpret`](super::gpu::Gpu::can_reinterpret)).
    pub ui_format: wgpu::TextureFormat,
    readback: wgpu::Buffer,
    pub size: (u32, u32),
    padded_row: u32,
}

/// An RGBA8 image, rows top to bottom.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub rgba: Vec<u8>,
}

impl Offscreen {
    /// `reinterpret`: whether the device can view the texture as [`UI_FORMAT`].
    pub fn new(device: &wgpu::Device, size: (u32, u32), reinterpret: bool) -> Self {
        let ui_format = if reinterpret { UI_FORMAT } else { FORMAT };
        let texture = super::texture_2d(
            device,
            "offscreen colour",
            size,
            FORMAT,
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            if reinterpret { &[UI_FORMAT] } else { &[] },
        );
        let view = texture.create_view(&Default::default());
        let ui_view = texture.create_view(&wgpu::TextureViewDescriptor {
            format: Some(ui_format),
            ..Default::default()
        });
        let padded_row = (4 * size.0).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
        let readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("offscreen readback"),
            size: u64::from(padded_row) * u64::from(size.1),
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        Offscreen {
            texture,
            view,
            ui_view,
            ui_format,
            readback,
            size,
            padded_row,
        }
    }

    /// Records the copy of the texture into the readback buffer.
    pub fn encode_copy(&self, encoder: &mut wgpu::CommandEncoder) {
        encoder.copy_texture_to_buffer(
            self.texture.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &self.readback,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(self.padded_row),
                    rows_per_image: Some(self.size.1),
                },
            },
            wgpu::Extent3d {
                width: self.size.0,
                height: self.size.1,
                depth_or_array_layers: 1,
            },
        );
    }

    /// Waits for the GPU and returns the image copied by [`Self::encode_copy`].
    pub fn read(&self, device: &wgpu::Device) -> anyhow::Result<Image> {
        let rows = read_buffer(device, &self.readback)?;
        let (w, h) = self.size;
        let mut rgba = Vec::with_capacity((4 * w * h) as usize);
        for row in rows.chunks(self.padded_row as usize).take(h as usize) {
            rgba.extend_from_slice(&row[..(4 * w) as usize]);
        }
        Ok(Image {
            width: w,
            height: h,
            rgba,
        })
    }
}

/// Maps a `MAP_READ` buffer, copies it out and unmaps it.
pub fn read_buffer(device: &wgpu::Device, buffer: &wgpu::Buffer) -> anyhow::Result<Vec<u8>> {
    let slice = buffer.slice(..);
    let (tx, rx) = std::sync::mpsc::sync_channel(1);
    slice.map_async(wgpu::MapMode::Read, move |r| {
        // The receiver waits below; a send error means it is gone, nothing to tell.
        let _ = tx.send(r);
    });
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| anyhow!("waiting for the GPU failed: {e}"))?;
    rx.recv()
        .context("the GPU dropped the read-back request")?
        .map_err(|e| anyhow!("mapping the read-back buffer failed: {e}"))?;
    let data = slice
        .get_mapped_range()
        .map_err(|e| anyhow!("reading the mapped buffer failed: {e:?}"))?
        .to_vec();
    buffer.unmap();
    Ok(data)
}

impl Image {
    /// Writes a PNG atomically (temp file, then rename).
    pub fn save_png(&self, path: &Path) -> anyhow::Result<()> {
        let mut bytes = Vec::new();
        {
            let mut enc = png::Encoder::new(&mut bytes, self.width, self.height);
            enc.set_color(png::ColorType::Rgba);
            enc.set_depth(png::BitDepth::Eight);
            let mut w = enc.write_header().context("PNG header")?;
            w.write_image_data(&self.rgba).context("PNG data")?;
        }
        palpa_core::fsutil::atomic_write(path, |w| std::io::Write::write_all(w, &bytes))
            .with_context(|| format!("writing {}", path.display()))
    }

    pub fn load_png(path: &Path) -> anyhow::Result<Self> {
        let file =
            std::fs::File::open(path).with_context(|| format!("opening {}", path.display()))?;
        let mut dec = png::Decoder::new(std::io::BufReader::new(file));
        dec.set_transformations(png::Transformations::EXPAND | png::Transformations::ALPHA);
        let mut reader = dec
            .read_info()
            .with_context(|| format!("{} is not a PNG", path.display()))?;
        let mut buf = vec![0; reader.output_buffer_size().context("PNG too large")?];
        let info = reader
            .next_frame(&mut buf)
            .with_context(|| format!("decoding {}", path.display()))?;
        buf.truncate(info.buffer_size());
        if info.color_type != png::ColorType::Rgba || info.bit_depth != png::BitDepth::Eight {
            anyhow::bail!(
                "{}: expected 8-bit RGBA, found {:?} {:?}",
                path.display(),
                info.color_type,
                info.bit_depth
            );
        }
        Ok(Image {
            width: info.width,
            height: info.height,
            rgba: buf,
        })
    }
}
