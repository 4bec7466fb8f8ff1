//! Whole-body 4D meshes: every slab of a stream welded into one closed mesh with its two
//! end caps, for consumers that need the body at once (the interference checker).

use super::march::{CapSide, TetMesh, Welder};
use super::mesher::{GridGeometry, Mesher, MesherOptions, Slab};
use super::stats::{BodyStats, StatsAccumulator};
use super::{FrameRef, MeshError, OccupancyGrid};

/// One body's closed 4D mesh over all its frames.
#[derive(Debug, Clone, Default)]
pub struct BodyMesh {
    /// Closed, welded mesh: lateral tets of every slab plus the first and last caps.
    pub mesh: TetMesh,
    /// Stamps of the accepted frames (ns); frame n is at lattice time `scale · n`.
    pub stamps_ns: Vec<i64>,
    /// The lattice, once a frame was accepted.
    pub geometry: Option<GridGeometry>,
    /// Decoded frames, if kept (see [`BodyAssembler::keep_frames`]).
    pub frames: Vec<OccupancyGrid>,
    /// Frames refused by the mesher.
    pub skipped: u64,
    /// Streaming statistics (closedness, hypervolume in m³·s, counts).
    pub stats: BodyStats,
}

/// Builds a [`BodyMesh`] from a stream of frames.
#[derive(Debug)]
pub struct BodyAssembler {
    mesher: Mesher,
    body: BodyMesh,
    welder: Welder,
    keep_frames: bool,
    acc: StatsAccumulator,
    first_cap: Option<TetMesh>,
}

impl BodyAssembler {
    /// A new assembler.
    ///
    /// # Errors
    /// Bad mesher options.
    pub fn new(opts: MesherOptions) -> Result<Self, MeshError> {
        Ok(Self {
            mesher: Mesher::new(opts)?,
            body: BodyMesh::default(),
            welder: Welder::default(),
            keep_frames: false,
            acc: StatsAccumulator::new(),
            first_cap: None,
        })
    }

    /// Also keep every decoded frame (for measures computed from occupancy).
    pub fn keep_frames(mut self, keep: bool) -> Self {
        self.keep_frames = keep;
        self
    }

    /// Feeds one frame.
    ///
    /// # Errors
    /// The mesher's reason for refusing the frame; it is skipped and counted.
    pub fn push(&mut self, f: &FrameRef<'_>) -> Result<(), MeshError> {
        let slab = self.mesher.push(f)?;
        self.after_accept(f.stamp_ns, slab);
        Ok(())
    }

    /// Feeds an already decoded frame (see [`Mesher::push_decoded`]).
    ///
    /// # Errors
    /// The mesher's reason for refusing the frame.
    pub fn push_decoded(
        &mut self,
        stamp_ns: i64,
        geometry: GridGeometry,
        grid: OccupancyGrid,
    ) -> Result<(), MeshError> {
        let slab = self.mesher.push_decoded(stamp_ns, geometry, grid)?;
        self.after_accept(stamp_ns, slab);
        Ok(())
    }

    fn after_accept(&mut self, stamp_ns: i64, slab: Option<Slab>) {
        self.body.stamps_ns.push(stamp_ns);
        if self.keep_frames {
            if let Some(k) = self.mesher.last_frame() {
                self.body.frames.push(k.grid.clone());
            }
        }
        if let Some(slab) = slab {
            if slab.index == 0 {
                self.first_cap = self
                    .mesher
                    .first_frame()
                    .and_then(|k| self.mesher.cap(k, CapSide::Low));
                if let Some(cap) = self.first_cap.take() {
                    self.weld(&cap);
                    self.first_cap = Some(cap);
                }
            }
            self.acc.add_slab(&slab, self.first_cap.as_ref());
            self.weld(&slab.mesh);
        }
    }

    fn weld(&mut self, part: &TetMesh) {
        self.welder.append(&mut self.body.mesh, part);
    }

    /// Closes the mesh with the last frame's cap and returns the body. With fewer than two
    /// frames the mesh is empty (a body needs a time extent).
    pub fn finish(mut self) -> BodyMesh {
        let mut last_cap = None;
        if self.mesher.frames() >= 2 {
            last_cap = self
                .mesher
                .last_frame()
                .and_then(|k| self.mesher.cap(k, CapSide::High));
            if let Some(cap) = &last_cap {
                self.weld(cap);
            }
        }
        let occ = |k: Option<&super::KeptFrame>| k.map_or(0, |k| k.grid.occupied);
        let (occ_first, occ_last) = (
            occ(self.mesher.first_frame()),
            occ(self.mesher.last_frame()),
        );
        self.body.stats = self.acc.finish(
            self.mesher.frames(),
            self.first_cap.as_ref().map(|c| (c, occ_first)),
            last_cap.as_ref().map(|c| (c, occ_last)),
        );
        self.body.geometry = self.mesher.geometry().copied();
        self.body.skipped = self.mesher.skipped();
        self.body
    }
}
