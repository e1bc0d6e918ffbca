//! Safe wrapper around Embree 3: the only `unsafe` code touching Embree.
//!
//! A [`Device`] is shared by reference counting, so an [`InstancedScene`]
//! owns what it needs and can live in structs and cross threads. Building
//! and moving instances take `&mut`; queries on the committed scene take `&`
//! and may run on many threads at once.

mod device;
mod fpenv;
mod raw;
mod scene;

pub(crate) use device::Device;
pub(crate) use raw::{RTCRay16, RTCRayHit, RTCRayHit16};
pub(crate) use scene::{ray1, ray_hit, InstancedScene, Valid16, INVALID_ID, PACKET};
