//! Pure-Rust Embree backend.
use super::{Accel, AccelError, Geometry, Hit, Ray, PACKET};

pub struct EmbreeScene;

impl EmbreeScene {
    pub fn build(geometry: &Geometry) -> Result<Self, AccelError> {
        let _ = geometry;
        todo!("embree")
    }
}

impl Accel for EmbreeScene {
    fn intersect(&self, _ray: &Ray) -> Option<Hit> {
        todo!()
    }
    fn occluded(&self, _ray: &Ray) -> bool {
        todo!()
    }
    fn intersect8(&self, _rays: &[Ray; PACKET], _active: u8, _hits: &mut [Option<Hit>; PACKET]) {
        todo!()
    }
    fn occluded8(&self, _rays: &[Ray; PACKET], _active: u8) -> u8 {
        todo!()
    }
    fn name(&self) -> &'static str {
        "embree"
    }
}
