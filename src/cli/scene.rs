//! `chronotope scene NAME --out FILE.mcap [--grid N] [--frames F] [--encoding bits|percent]`.

use super::CliError;
use super::EncodingArg;
use crate::bag::BagWriter;
use crate::msg::VoxelGrid;
use crate::scene::{build_scene, Rasterizer, SceneName, SceneOptions};
use clap::Args;
use std::path::PathBuf;

/// Options of `chronotope scene`.
#[derive(Debug, Clone, Args)]
pub struct SceneArgs {
    /// `machine-tool` or `four-spheres`.
    pub name: SceneName,
    /// Output bag.
    #[arg(long)]
    pub out: PathBuf,
    /// Voxels per edge of the cubic domain (default: the scene's).
    #[arg(long)]
    pub grid: Option<u32>,
    /// Frames per body (default: the scene's).
    #[arg(long)]
    pub frames: Option<u32>,
    /// Voxel encoding.
    #[arg(long, value_enum, default_value_t = EncodingArg::Bits)]
    pub encoding: EncodingArg,
}

/// Writes the scene bag: frames in time order, bodies interleaved, log time = stamp.
///
/// # Errors
/// Bad options or a bag that cannot be written.
pub fn run(a: &SceneArgs) -> Result<(), CliError> {
    let mut opts = SceneOptions::for_scene(a.name).encoding(a.encoding.into());
    if let Some(g) = a.grid {
        opts = opts.grid(g);
    }
    if let Some(f) = a.frames {
        opts = opts.frames(f);
    }
    let scene = build_scene(a.name, &opts)?;
    let mut w = BagWriter::create(&a.out)?;
    let topics = scene.topics();
    for t in &topics {
        w.add_topic::<VoxelGrid>(t)?;
    }
    let mut raster = Rasterizer::new();
    let mut grid = VoxelGrid::default();
    for k in 0..scene.frame_count() {
        for (b, t) in topics.iter().enumerate() {
            scene.write_frame(b, k, &mut raster, &mut grid)?;
            w.write(t, scene.stamp_ns(k) as u64, &grid)?;
        }
    }
    w.finish()?;
    tracing::info!(
        "wrote {} ({} bodies x {} frames, {}^3 voxels, {:?})",
        a.out.display(),
        topics.len(),
        scene.frame_count(),
        opts.grid,
        opts.encoding
    );
    Ok(())
}
