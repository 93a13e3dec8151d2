//! Counters at the points where data crosses from host to device. Nothing
//! here estimates: a byte is counted when it is written into host-visible
//! memory that the device reads directly, or when a transfer command copies it
//! from host-visible into device-local memory. A staged upload counts once (at
//! the copy), so no byte is counted twice.

use serde::Serialize;

/// When a byte crosses: once at set-up, or again every frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum UploadClass {
    /// One-time data (index buffers, tables); reported apart from frames.
    Static,
    /// Per-frame data that scales with the number of cells (vertex records).
    FrameCells,
    /// Per-frame data independent of the cell count (camera constants).
    FrameConstants,
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct UploadCounter {
    /// Bytes the host wrote into host-visible memory the device reads in place.
    pub direct_static: u64,
    pub direct_frame_cells: u64,
    pub direct_frame_constants: u64,
    /// Bytes copied by transfer commands from host-visible to device-local memory.
    pub transfer_static: u64,
    pub transfer_frame_cells: u64,
    pub transfer_frame_constants: u64,
}

impl UploadCounter {
    pub fn add_direct(&mut self, class: UploadClass, bytes: u64) {
        match class {
            UploadClass::Static => self.direct_static += bytes,
            UploadClass::FrameCells => self.direct_frame_cells += bytes,
            UploadClass::FrameConstants => self.direct_frame_constants += bytes,
        }
    }

    pub fn add_transfer(&mut self, class: UploadClass, bytes: u64) {
        match class {
            UploadClass::Static => self.transfer_static += bytes,
            UploadClass::FrameCells => self.transfer_frame_cells += bytes,
            UploadClass::FrameConstants => self.transfer_frame_constants += bytes,
        }
    }

    pub fn static_bytes(&self) -> u64 {
        self.direct_static + self.transfer_static
    }

    pub fn frame_cell_bytes(&self) -> u64 {
        self.direct_frame_cells + self.transfer_frame_cells
    }

    pub fn frame_constant_bytes(&self) -> u64 {
        self.direct_frame_constants + self.transfer_frame_constants
    }

    /// Everything that crossed per frame (cells and constants).
    pub fn frame_bytes(&self) -> u64 {
        self.frame_cell_bytes() + self.frame_constant_bytes()
    }

    /// Difference `self - earlier`, e.g. one frame's worth.
    pub fn since(&self, earlier: &UploadCounter) -> UploadCounter {
        UploadCounter {
            direct_static: self.direct_static - earlier.direct_static,
            direct_frame_cells: self.direct_frame_cells - earlier.direct_frame_cells,
            direct_frame_constants: self.direct_frame_constants - earlier.direct_frame_constants,
            transfer_static: self.transfer_static - earlier.transfer_static,
            transfer_frame_cells: self.transfer_frame_cells - earlier.transfer_frame_cells,
            transfer_frame_constants: self.transfer_frame_constants - earlier.transfer_frame_constants,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn classes_are_kept_apart() {
        let mut c = UploadCounter::default();
        c.add_direct(UploadClass::FrameCells, 112);
        c.add_direct(UploadClass::FrameConstants, 96);
        c.add_transfer(UploadClass::Static, 28);
        assert_eq!(c.frame_cell_bytes(), 112);
        assert_eq!(c.frame_bytes(), 208);
        assert_eq!(c.static_bytes(), 28);
        let later = { let mut l = c; l.add_direct(UploadClass::FrameCells, 112); l };
        assert_eq!(later.since(&c).frame_cell_bytes(), 112);
        assert_eq!(later.since(&c).static_bytes(), 0);
    }
}
