//! The Embree backend: the only file that calls Embree (through `embree-sys`).
//!
//! One device per scene with an error callback that records Embree's errors so they surface
//! as [`AccelError`]s; the triangle soup as one triangle geometry over shared buffers, the
//! spheres as one sphere-point geometry; MEDIUM build quality (shared/notes/embree.md: HIGH
//! costs several times the build for ~13% faster traversal). Written against Embree 3's API.

use super::{sphere_roots, Accel, AccelError, Geometry, Hit, Primitive, Ray, Sphere, PACKET};
use embree_sys as sys;
use glam::Vec3;
use std::cell::Cell;
use std::ffi::{c_void, CStr};
use std::sync::Mutex;

/// Errors reported by the device callback since the last check.
#[derive(Default)]
struct ErrorLog(Mutex<Option<(u32, String)>>);

unsafe extern "C" fn record_error(
    user: *mut c_void,
    code: sys::RTCError,
    message: *const std::ffi::c_char,
) {
    // SAFETY: `user` is the `ErrorLog` boxed in `EmbreeScene`, alive as long as the device;
    // `message` is a NUL-terminated string owned by Embree for the duration of the call.
    let (log, text) = unsafe {
        let text = if message.is_null() {
            String::new()
        } else {
            CStr::from_ptr(message).to_string_lossy().into_owned()
        };
        (&*(user as *const ErrorLog), text)
    };
    if let Ok(mut slot) = log.0.lock() {
        slot.get_or_insert((code as u32, text));
    }
}

pub struct EmbreeScene {
    device: sys::RTCDevice,
    scene: sys::RTCScene,
    errors: Box<ErrorLog>,
    /// Buffers Embree reads in place: kept alive and unmoved as long as the scene.
    _vertices: Vec<[f32; 4]>,
    _indices: Vec<[u32; 3]>,
    _spheres: Vec<[f32; 4]>,
    spheres: Vec<Sphere>,
    triangle_geometry: u32,
    sphere_geometry: u32,
}

// SAFETY: after `rtcCommitScene`, Embree scenes are immutable and Embree documents
// rtcIntersect*/rtcOccluded* as thread-safe on a committed scene; the device and scene handles
// are only released in `Drop`, which needs exclusive ownership.
unsafe impl Send for EmbreeScene {}
// SAFETY: as above: every `&self` method only issues thread-safe queries.
unsafe impl Sync for EmbreeScene {}

impl EmbreeScene {
    pub fn build(geometry: &Geometry) -> Result<Self, AccelError> {
        Self::build_with_config(geometry, "")
    }

    /// Builds with an Embree device configuration string (e.g. `"threads=1,verbose=1"`).
    pub fn build_with_config(geometry: &Geometry, config: &str) -> Result<Self, AccelError> {
        let errors = Box::<ErrorLog>::default();
        let config = std::ffi::CString::new(config).map_err(|_| AccelError::Embree {
            code: 0,
            message: "device configuration contains NUL".into(),
        })?;
        // SAFETY: `config` is a valid NUL-terminated string for the duration of the call.
        let device = unsafe { sys::rtcNewDevice(config.as_ptr()) };
        if device.is_null() {
            // SAFETY: a null device asks for the error of the failed device creation.
            let code = unsafe { sys::rtcGetDeviceError(std::ptr::null_mut()) };
            return Err(AccelError::Embree {
                code: code as u32,
                message: format!("rtcNewDevice failed: {code:?}"),
            });
        }
        // SAFETY: `errors` is boxed, so its address is stable for the device's lifetime (the
        // device is released before `errors` in Drop).
        unsafe {
            sys::rtcSetDeviceErrorFunction(
                device,
                Some(record_error),
                &*errors as *const ErrorLog as *mut c_void,
            )
        };
        // SAFETY: `device` is valid.
        let scene = unsafe { sys::rtcNewScene(device) };
        let mut this = EmbreeScene {
            device,
            scene,
            errors,
            _vertices: geometry
                .positions
                .iter()
                .map(|p| [p.x, p.y, p.z, 0.0])
                .collect(),
            _indices: geometry.triangles.clone(),
            _spheres: geometry
                .spheres
                .iter()
                .map(|s| [s.center.x, s.center.y, s.center.z, s.radius])
                .collect(),
            spheres: geometry.spheres.clone(),
            triangle_geometry: sys::RTC_INVALID_GEOMETRY_ID,
            sphere_geometry: sys::RTC_INVALID_GEOMETRY_ID,
        };
        this.check()?;
        // SAFETY: `scene` is valid.
        unsafe {
            sys::rtcSetSceneBuildQuality(scene, sys::RTCBuildQuality_RTC_BUILD_QUALITY_MEDIUM)
        };
        if !this._indices.is_empty() {
            this.triangle_geometry = this.attach(
                sys::RTCGeometryType_RTC_GEOMETRY_TYPE_TRIANGLE,
                &[
                    (
                        sys::RTCBufferType_RTC_BUFFER_TYPE_VERTEX,
                        sys::RTCFormat_RTC_FORMAT_FLOAT3,
                        this._vertices.as_ptr().cast(),
                        16,
                        this._vertices.len(),
                    ),
                    (
                        sys::RTCBufferType_RTC_BUFFER_TYPE_INDEX,
                        sys::RTCFormat_RTC_FORMAT_UINT3,
                        this._indices.as_ptr().cast(),
                        12,
                        this._indices.len(),
                    ),
                ],
            )?;
        }
        if !this._spheres.is_empty() {
            this.sphere_geometry = this.attach(
                sys::RTCGeometryType_RTC_GEOMETRY_TYPE_SPHERE_POINT,
                &[(
                    sys::RTCBufferType_RTC_BUFFER_TYPE_VERTEX,
                    sys::RTCFormat_RTC_FORMAT_FLOAT4,
                    this._spheres.as_ptr().cast(),
                    16,
                    this._spheres.len(),
                )],
            )?;
        }
        // SAFETY: `scene` is valid and every attached buffer is alive in `this`.
        unsafe { sys::rtcCommitScene(scene) };
        this.check()?;
        Ok(this)
    }

    /// Creates a geometry over shared buffers `(type, format, pointer, stride, count)`,
    /// commits and attaches it; returns its id.
    fn attach(
        &self,
        kind: sys::RTCGeometryType,
        buffers: &[(
            sys::RTCBufferType,
            sys::RTCFormat,
            *const c_void,
            usize,
            usize,
        )],
    ) -> Result<u32, AccelError> {
        // SAFETY: `device` is valid.
        let geometry = unsafe { sys::rtcNewGeometry(self.device, kind) };
        self.check()?;
        for &(buffer, format, pointer, stride, count) in buffers {
            // SAFETY: `pointer` points to `count` items of `stride` bytes owned by `self`
            // and never moved or freed before the scene; vertex buffers are 16-byte items, so
            // Embree's 16-byte reads of the last vertex stay inside the allocation.
            unsafe {
                sys::rtcSetSharedGeometryBuffer(
                    geometry, buffer, 0, format, pointer, 0, stride, count,
                )
            };
        }
        // SAFETY: `geometry` and `scene` are valid; attaching retains the geometry, so our
        // reference is released right after.
        let id = unsafe {
            sys::rtcCommitGeometry(geometry);
            let id = sys::rtcAttachGeometry(self.scene, geometry);
            sys::rtcReleaseGeometry(geometry);
            id
        };
        self.check()?;
        Ok(id)
    }

    /// Turns the first error Embree reported (by callback or error code) into a Rust error.
    fn check(&self) -> Result<(), AccelError> {
        let recorded = self.errors.0.lock().ok().and_then(|mut slot| slot.take());
        // SAFETY: `device` is valid.
        let code = unsafe { sys::rtcGetDeviceError(self.device) };
        match (recorded, code) {
            (Some((code, message)), _) => Err(AccelError::Embree { code, message }),
            (None, sys::RTCError::RTC_ERROR_NONE) => Ok(()),
            (None, code) => Err(AccelError::Embree {
                code: code as u32,
                message: format!("{code:?}"),
            }),
        }
    }

    fn context(coherent: bool) -> sys::RTCIntersectContext {
        // rtcInitIntersectContext is an inline header function, re-implemented here.
        sys::RTCIntersectContext {
            flags: if coherent {
                sys::RTCIntersectContextFlags_RTC_INTERSECT_CONTEXT_FLAG_COHERENT
            } else {
                sys::RTCIntersectContextFlags_RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT
            },
            filter: None,
            instID: [sys::RTC_INVALID_GEOMETRY_ID],
        }
    }

    /// The [`Hit`] of Embree's answer for `ray`. Inlined for the common triangle case, the
    /// sphere case kept out of line: this runs once per ray and lane.
    #[inline]
    fn hit(&self, h: RawHit, ray: &Ray) -> Option<Hit> {
        let RawHit {
            geom_id,
            prim_id,
            t,
            u,
            v,
            ng,
        } = h;
        if geom_id == self.triangle_geometry {
            // Embree's Ng (same winding as the Hit contract) rather than one recomputed from
            // the vertices: reading those again is a cache miss on large meshes.
            Some(Hit {
                t,
                primitive: Primitive::Triangle(prim_id),
                u,
                v,
                ng,
            })
        } else if geom_id == self.sphere_geometry {
            Some(self.sphere_hit(prim_id, t, ray))
        } else {
            None
        }
    }

    #[inline(never)]
    fn sphere_hit(&self, prim_id: u32, t: f32, ray: &Ray) -> Hit {
        // Embree's single-ray and packet sphere tests round differently; the exact root
        // nearest Embree's makes both (and the Rust BVH) report the same bits.
        let sphere = &self.spheres[prim_id as usize];
        let t = sphere_roots(sphere, ray).map_or(t, |[t0, t1]| {
            if (t0 - t).abs() <= (t1 - t).abs() {
                t0
            } else {
                t1
            }
        });
        let ng = (ray.at(t) - sphere.center).normalize();
        Hit {
            t,
            primitive: Primitive::Sphere(prim_id),
            u: 0.0,
            v: 0.0,
            ng,
        }
    }
}

/// One ray's answer from Embree.
struct RawHit {
    geom_id: u32,
    prim_id: u32,
    t: f32,
    u: f32,
    v: f32,
    /// Embree's unnormalised geometric normal.
    ng: Vec3,
}

fn rtc_ray(ray: &Ray) -> sys::RTCRay {
    sys::RTCRay {
        org_x: ray.origin.x,
        org_y: ray.origin.y,
        org_z: ray.origin.z,
        tnear: ray.tmin,
        dir_x: ray.dir.x,
        dir_y: ray.dir.y,
        dir_z: ray.dir.z,
        time: 0.0,
        tfar: ray.tmax,
        // Debian's Embree is built with ray masks: a zero mask misses everything.
        mask: u32::MAX,
        id: 0,
        flags: 0,
    }
}

fn empty_hit() -> sys::RTCHit {
    sys::RTCHit {
        geomID: sys::RTC_INVALID_GEOMETRY_ID,
        instID: [sys::RTC_INVALID_GEOMETRY_ID],
        ..Default::default()
    }
}

/// 8-wide packet structures must be 32-byte aligned (the `valid` mask too).
#[repr(C, align(32))]
struct ValidMask([i32; PACKET]);

fn packet_rays(rays: &[Ray; PACKET], active: u8) -> (ValidMask, sys::RTCRay8) {
    let mut valid = ValidMask([0; PACKET]);
    let mut r = sys::RTCRay8 {
        org_x: [0.0; PACKET],
        org_y: [0.0; PACKET],
        org_z: [0.0; PACKET],
        tnear: [0.0; PACKET],
        dir_x: [0.0; PACKET],
        dir_y: [0.0; PACKET],
        dir_z: [0.0; PACKET],
        time: [0.0; PACKET],
        tfar: [0.0; PACKET],
        mask: [u32::MAX; PACKET],
        id: [0; PACKET],
        flags: [0; PACKET],
    };
    for (i, ray) in rays.iter().enumerate() {
        valid.0[i] = if active & (1 << i) != 0 { -1 } else { 0 };
        r.org_x[i] = ray.origin.x;
        r.org_y[i] = ray.origin.y;
        r.org_z[i] = ray.origin.z;
        r.tnear[i] = ray.tmin;
        r.dir_x[i] = ray.dir.x;
        r.dir_y[i] = ray.dir.y;
        r.dir_z[i] = ray.dir.z;
        r.tfar[i] = ray.tmax;
        r.id[i] = i as u32;
    }
    (valid, r)
}

thread_local! {
    static FLUSH_DENORMALS_SET: Cell<bool> = const { Cell::new(false) };
}

/// Embree wants flush-to-zero and denormals-are-zero in every thread that traces.
#[inline]
fn ensure_flush_denormals() {
    FLUSH_DENORMALS_SET.with(|set| {
        if !set.get() {
            #[cfg(target_arch = "x86_64")]
            {
                let mut csr: u32 = 0;
                // SAFETY: stmxcsr/ldmxcsr read and write this thread's SSE control register;
                // setting FTZ (bit 15) and DAZ (bit 6) changes only denormal handling.
                unsafe {
                    std::arch::asm!("stmxcsr [{}]", in(reg) &mut csr, options(nostack));
                    csr |= 0x8040;
                    std::arch::asm!("ldmxcsr [{}]", in(reg) &csr, options(nostack));
                }
            }
            set.set(true);
        }
    });
}

impl Accel for EmbreeScene {
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        ensure_flush_denormals();
        let mut context = Self::context(false);
        let mut rayhit = sys::RTCRayHit {
            ray: rtc_ray(ray),
            hit: empty_hit(),
        };
        // SAFETY: the scene is committed; context and rayhit are valid for the call.
        unsafe { sys::rtcIntersect1(self.scene, &mut context, &mut rayhit) };
        let h = &rayhit.hit;
        if h.geomID == sys::RTC_INVALID_GEOMETRY_ID {
            return None;
        }
        self.hit(
            RawHit {
                geom_id: h.geomID,
                prim_id: h.primID,
                t: rayhit.ray.tfar,
                u: h.u,
                v: h.v,
                ng: Vec3::new(h.Ng_x, h.Ng_y, h.Ng_z),
            },
            ray,
        )
    }

    fn occluded(&self, ray: &Ray) -> bool {
        ensure_flush_denormals();
        let mut context = Self::context(false);
        let mut r = rtc_ray(ray);
        // SAFETY: as for rtcIntersect1.
        unsafe { sys::rtcOccluded1(self.scene, &mut context, &mut r) };
        // A hit sets tfar to -inf; a miss leaves it unchanged.
        r.tfar == f32::NEG_INFINITY
    }

    fn intersect8(&self, rays: &[Ray; PACKET], active: u8, hits: &mut [Option<Hit>; PACKET]) {
        ensure_flush_denormals();
        let mut context = Self::context(false);
        let (valid, ray8) = packet_rays(rays, active);
        let hit8 = sys::RTCHit8 {
            geomID: [sys::RTC_INVALID_GEOMETRY_ID; PACKET],
            instID: [[sys::RTC_INVALID_GEOMETRY_ID; PACKET]],
            ..Default::default()
        };
        let mut rayhit = sys::RTCRayHit8 {
            ray: ray8,
            hit: hit8,
        };
        // SAFETY: `valid` and `rayhit` are 32-byte aligned (RTCRayHit8 by bindgen's repr,
        // ValidMask by ours) and live for the call; the scene is committed.
        unsafe { sys::rtcIntersect8(valid.0.as_ptr(), self.scene, &mut context, &mut rayhit) };
        for (i, (ray, out)) in rays.iter().zip(hits.iter_mut()).enumerate() {
            let h = &rayhit.hit;
            *out = if active & (1 << i) != 0 && h.geomID[i] != sys::RTC_INVALID_GEOMETRY_ID {
                self.hit(
                    RawHit {
                        geom_id: h.geomID[i],
                        prim_id: h.primID[i],
                        t: rayhit.ray.tfar[i],
                        u: h.u[i],
                        v: h.v[i],
                        ng: Vec3::new(h.Ng_x[i], h.Ng_y[i], h.Ng_z[i]),
                    },
                    ray,
                )
            } else {
                None
            };
        }
    }

    fn occluded8(&self, rays: &[Ray; PACKET], active: u8) -> u8 {
        ensure_flush_denormals();
        let mut context = Self::context(false);
        let (valid, mut ray8) = packet_rays(rays, active);
        // SAFETY: as for rtcIntersect8.
        unsafe { sys::rtcOccluded8(valid.0.as_ptr(), self.scene, &mut context, &mut ray8) };
        (0..PACKET)
            .filter(|&i| active & (1 << i) != 0 && ray8.tfar[i] == f32::NEG_INFINITY)
            .fold(0u8, |mask, i| mask | (1 << i))
    }

    fn name(&self) -> &'static str {
        "embree"
    }
}

impl Drop for EmbreeScene {
    fn drop(&mut self) {
        // SAFETY: both handles are valid and owned; the scene goes before its device, and the
        // error log (a field dropped after this) outlives the device.
        unsafe {
            sys::rtcReleaseScene(self.scene);
            sys::rtcReleaseDevice(self.device);
        }
    }
}

/// A triangle scene built and queried through raw `embree-sys` calls, with none of
/// [`EmbreeScene`]'s conversions, so benchmarks can measure what the safe wrapper costs. Not
/// part of the renderer's interface.
#[doc(hidden)]
pub struct RawScene {
    device: sys::RTCDevice,
    scene: sys::RTCScene,
}

impl RawScene {
    /// The triangles of `geometry` (its spheres are left out), in an Embree-owned buffer.
    pub fn build(geometry: &Geometry) -> Result<Self, AccelError> {
        let embree_error = |device| {
            // SAFETY: `device` is a valid device handle or null, which asks for the error of
            // the failed device creation.
            let code = unsafe { sys::rtcGetDeviceError(device) };
            (code != sys::RTCError::RTC_ERROR_NONE).then(|| AccelError::Embree {
                code: code as u32,
                message: format!("{code:?}"),
            })
        };
        if let Some(i) = geometry
            .triangles
            .iter()
            .position(|t| t.iter().any(|&v| v as usize >= geometry.positions.len()))
        {
            return Err(AccelError::InvalidGeometry(format!(
                "triangle {i} indexes a vertex beyond the {} given",
                geometry.positions.len()
            )));
        }
        // SAFETY: a null configuration string asks for the defaults.
        let device = unsafe { sys::rtcNewDevice(std::ptr::null()) };
        if device.is_null() {
            return Err(
                embree_error(std::ptr::null_mut()).unwrap_or(AccelError::Embree {
                    code: 0,
                    message: "rtcNewDevice failed".into(),
                }),
            );
        }
        // SAFETY: `device` is valid; the scene owns the geometry after attaching, so our
        // reference is released.
        let scene = unsafe {
            let scene = sys::rtcNewScene(device);
            sys::rtcSetSceneBuildQuality(scene, sys::RTCBuildQuality_RTC_BUILD_QUALITY_MEDIUM);
            let mesh = sys::rtcNewGeometry(device, sys::RTCGeometryType_RTC_GEOMETRY_TYPE_TRIANGLE);
            sys::rtcAttachGeometry(scene, mesh);
            sys::rtcReleaseGeometry(mesh);
            scene
        };
        let raw = RawScene { device, scene };
        if let Some(e) = embree_error(device) {
            return Err(e);
        }
        // SAFETY: geometry 0 is the mesh attached above; Embree allocates each buffer with
        // `count * stride` bytes (plus its padding for 16-byte vertex reads), 4-byte aligned,
        // so it is valid as a slice of that many `[f32; 3]` / `[u32; 3]` until the scene is
        // released, and nothing else accesses it before the commit.
        unsafe {
            let mesh = sys::rtcGetGeometry(scene, 0);
            let vertices = sys::rtcSetNewGeometryBuffer(
                mesh,
                sys::RTCBufferType_RTC_BUFFER_TYPE_VERTEX,
                0,
                sys::RTCFormat_RTC_FORMAT_FLOAT3,
                12,
                geometry.positions.len(),
            ) as *mut [f32; 3];
            let indices = sys::rtcSetNewGeometryBuffer(
                mesh,
                sys::RTCBufferType_RTC_BUFFER_TYPE_INDEX,
                0,
                sys::RTCFormat_RTC_FORMAT_UINT3,
                12,
                geometry.triangles.len(),
            ) as *mut [u32; 3];
            if !vertices.is_null() && !indices.is_null() {
                std::slice::from_raw_parts_mut(vertices, geometry.positions.len())
                    .iter_mut()
                    .zip(&geometry.positions)
                    .for_each(|(out, p)| *out = p.to_array());
                std::slice::from_raw_parts_mut(indices, geometry.triangles.len())
                    .copy_from_slice(&geometry.triangles);
                sys::rtcCommitGeometry(mesh);
                sys::rtcCommitScene(scene);
            }
        }
        match embree_error(device) {
            Some(e) => Err(e),
            None => Ok(raw),
        }
    }

    /// Closest hits of `rays` through `rtcIntersect1`; returns how many hit.
    pub fn intersect1(&self, rays: &[Ray]) -> u64 {
        ensure_flush_denormals();
        let mut context = EmbreeScene::context(false);
        let mut hits = 0;
        for ray in rays {
            let mut rayhit = sys::RTCRayHit {
                ray: rtc_ray(ray),
                hit: empty_hit(),
            };
            // SAFETY: the scene is committed; context and rayhit are valid for the call.
            unsafe { sys::rtcIntersect1(self.scene, &mut context, &mut rayhit) };
            hits += (rayhit.hit.geomID != sys::RTC_INVALID_GEOMETRY_ID) as u64;
        }
        hits
    }

    /// Occlusion of `rays` through `rtcOccluded1`; returns how many are occluded.
    pub fn occluded1(&self, rays: &[Ray]) -> u64 {
        ensure_flush_denormals();
        let mut context = EmbreeScene::context(false);
        let mut occluded = 0;
        for ray in rays {
            let mut r = rtc_ray(ray);
            // SAFETY: as for rtcIntersect1.
            unsafe { sys::rtcOccluded1(self.scene, &mut context, &mut r) };
            occluded += (r.tfar == f32::NEG_INFINITY) as u64;
        }
        occluded
    }

    /// Closest hits of `rays`, 8 at a time through `rtcIntersect8` (a partial last packet is
    /// left out); returns how many hit.
    pub fn intersect8(&self, rays: &[Ray]) -> u64 {
        ensure_flush_denormals();
        let mut context = EmbreeScene::context(false);
        let mut hits = 0;
        for chunk in rays.chunks_exact(PACKET) {
            let Ok(packet) = <&[Ray; PACKET]>::try_from(chunk) else {
                continue;
            };
            let (valid, ray) = packet_rays(packet, 0xff);
            let mut rayhit = sys::RTCRayHit8 {
                ray,
                hit: sys::RTCHit8 {
                    geomID: [sys::RTC_INVALID_GEOMETRY_ID; PACKET],
                    instID: [[sys::RTC_INVALID_GEOMETRY_ID; PACKET]],
                    ..Default::default()
                },
            };
            // SAFETY: `valid` and `rayhit` are 32-byte aligned and live for the call; the
            // scene is committed.
            unsafe { sys::rtcIntersect8(valid.0.as_ptr(), self.scene, &mut context, &mut rayhit) };
            hits += rayhit
                .hit
                .geomID
                .iter()
                .filter(|&&g| g != sys::RTC_INVALID_GEOMETRY_ID)
                .count() as u64;
        }
        hits
    }

    /// Occlusion of `rays`, 8 at a time through `rtcOccluded8`; returns how many are occluded.
    pub fn occluded8(&self, rays: &[Ray]) -> u64 {
        ensure_flush_denormals();
        let mut context = EmbreeScene::context(false);
        let mut occluded = 0;
        for chunk in rays.chunks_exact(PACKET) {
            let Ok(packet) = <&[Ray; PACKET]>::try_from(chunk) else {
                continue;
            };
            let (valid, mut ray) = packet_rays(packet, 0xff);
            // SAFETY: as for rtcIntersect8.
            unsafe { sys::rtcOccluded8(valid.0.as_ptr(), self.scene, &mut context, &mut ray) };
            occluded += ray.tfar.iter().filter(|&&t| t == f32::NEG_INFINITY).count() as u64;
        }
        occluded
    }
}

impl Drop for RawScene {
    fn drop(&mut self) {
        // SAFETY: both handles are valid and owned; the scene goes before its device.
        unsafe {
            sys::rtcReleaseScene(self.scene);
            sys::rtcReleaseDevice(self.device);
        }
    }
}
