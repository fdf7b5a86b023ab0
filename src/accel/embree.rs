//! The Embree backend: the only file that calls Embree (through `embree-sys`).
//!
//! One device per scene with an error callback that records Embree's errors so they surface
//! as [`AccelError`]s; the triangle soup as one triangle geometry per group over shared buffers
//! (a geometry's id is its group's number, so a hit names its group and triangle without a
//! table; Embree still builds one BVH over all of them), the spheres as one sphere-point
//! geometry, or, when there are only a few, tested by vmerge beside Embree's traversal
//! ([`SphereTests`]); MEDIUM build quality (shared/notes/embree.md: HIGH costs several times
//! the build for ~13% faster traversal). Speaks Embree 3's and 4's APIs (`cfg(embree3)` /
//! `cfg(embree4)`, from the version embree-sys found): only the ray queries differ, in `query`;
//! both versions are asked the same questions.
//!
//! Cut-out triangles (`alpha.rs`) form a geometry of their own whose intersection and
//! occlusion filter functions drop the hits their alpha removes, for single rays and packets
//! alike; the opaque triangles stay in a geometry without filters, so they cost what they did.
//! A scene with cut-outs keeps its opaque triangles in one geometry and finds a hit's group
//! from the group starts.

use super::{
    group_of, sphere_roots, Accel, AccelError, Cutouts, Geometry, Hit, Primitive, Ray, Sphere,
    PACKET,
};
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

/// Who tests a scene's spheres.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SphereTests {
    /// Embree, as one sphere-point geometry beside the triangles.
    Embree,
    /// vmerge, every sphere for every ray, before Embree traces the triangles alone.
    Direct,
}

impl SphereTests {
    /// Up to this many spheres are tested directly. A second geometry type makes Embree
    /// traverse a second acceleration structure for every ray, whether or not the ray comes
    /// near a sphere: on SmallVCM's box of 20 triangles one tiny sphere that no ray hits made a
    /// one-thread `pt` render 1.2x slower, where a direct test costs a few nanoseconds a sphere.
    /// Direct against Embree's spheres, that box with n mirror spheres, one-thread `pt`: 0.82-0.90
    /// of the time at n = 4, 0.95-1.01 at 8, 1.03-1.06 at 16, 1.29-1.31 at 32.
    const DIRECT_MAX: usize = 4;

    /// The faster way for `count` spheres.
    pub fn for_count(count: usize) -> Self {
        if count <= Self::DIRECT_MAX {
            SphereTests::Direct
        } else {
            SphereTests::Embree
        }
    }
}

/// What the filter functions of the cut-out geometry read: the geometry's triangles by
/// Embree's primitive id, and their alphas.
struct CutoutFilter {
    triangles: Vec<u32>,
    cutouts: Cutouts,
}

/// The intersection and occlusion filter of the cut-out geometry: clears the `valid` lane of
/// each hit whose alpha removes it, so Embree goes on as if the triangle were not there.
unsafe extern "C" fn cutout_filter(args: *const sys::RTCFilterFunctionNArguments) {
    // SAFETY: Embree passes valid arguments for the call: `valid` holds N lanes, `ray` and
    // `hit` are RTCRayN / RTCHitN of N lanes, laid out as rtcore_ray.h's accessors read them
    // (structure of arrays, 4-byte fields: origin x, y, z at fields 0-2, direction at 4-6; u, v
    // at hit fields 3-4, primID at 5); `geometryUserPtr` is the boxed `CutoutFilter` of the
    // scene, alive as long as the scene; primitive ids index its triangles.
    unsafe {
        let args = &*args;
        let n = args.N as usize;
        let filter = &*(args.geometryUserPtr as *const CutoutFilter);
        let valid = std::slice::from_raw_parts_mut(args.valid, n);
        let ray = std::slice::from_raw_parts(args.ray as *const f32, 7 * n);
        let hit = std::slice::from_raw_parts(args.hit as *const u32, 6 * n);
        for (i, lane) in valid.iter_mut().enumerate() {
            if *lane == 0 {
                continue;
            }
            let field = |k: usize| ray[k * n + i];
            let query = Ray {
                origin: Vec3::new(field(0), field(1), field(2)),
                dir: Vec3::new(field(4), field(5), field(6)),
                tmin: field(3),
                tmax: f32::INFINITY,
            };
            let (u, v) = (
                f32::from_bits(hit[3 * n + i]),
                f32::from_bits(hit[4 * n + i]),
            );
            let Some(&triangle) = filter.triangles.get(hit[5 * n + i] as usize) else {
                continue;
            };
            if !filter.cutouts.keeps(triangle, u, v, &query) {
                *lane = 0;
            }
        }
    }
}

pub struct EmbreeScene {
    device: sys::RTCDevice,
    scene: sys::RTCScene,
    errors: Box<ErrorLog>,
    /// Buffers Embree reads in place: kept alive and unmoved as long as the scene.
    _vertices: Vec<[f32; 4]>,
    /// The opaque triangles (all of them in a scene without cut-outs).
    _indices: Vec<[u32; 3]>,
    /// The cut-out triangles.
    _cutout_indices: Vec<[u32; 3]>,
    _spheres: Vec<[f32; 4]>,
    /// Without cut-outs, the first triangle of each group, by geometry id (the group's
    /// number); empty with cut-outs.
    group_first: Vec<u32>,
    /// With cut-outs, the opaque geometry's triangles by primitive id.
    opaque_triangles: Vec<u32>,
    /// [`Geometry::group_starts`], for the groups of hits on the geometries of a scene with
    /// cut-outs.
    group_starts: Vec<u32>,
    /// Read by the filter functions through Embree: boxed, so its address is stable.
    filter: Box<CutoutFilter>,
    /// The spheres Embree holds, to make their hits exact; empty when vmerge tests them.
    spheres: Vec<Sphere>,
    /// The spheres vmerge tests itself ([`SphereTests::Direct`]); empty when Embree holds them.
    direct_spheres: Vec<Sphere>,
    triangle_geometry: u32,
    cutout_geometry: u32,
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
        let spheres = SphereTests::for_count(geometry.spheres.len());
        Self::build_with(geometry, config, spheres)
    }

    /// Builds with a device configuration string and the spheres tested as `spheres` says.
    pub fn build_with(
        geometry: &Geometry,
        config: &str,
        spheres: SphereTests,
    ) -> Result<Self, AccelError> {
        check_indices(geometry)?;
        geometry.check_groups()?;
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
        let (embree_spheres, direct_spheres) = match spheres {
            SphereTests::Embree => (geometry.spheres.clone(), Vec::new()),
            SphereTests::Direct => (Vec::new(), geometry.spheres.clone()),
        };
        let (opaque_triangles, cutout_triangles): (Vec<u32>, Vec<u32>) =
            if geometry.cutouts.is_empty() {
                (Vec::new(), Vec::new())
            } else {
                (0..geometry.triangles.len() as u32)
                    .partition(|&i| geometry.cutouts.get(i).is_none())
            };
        let indices = |ids: &[u32]| -> Vec<[u32; 3]> {
            ids.iter()
                .map(|&i| geometry.triangles[i as usize])
                .collect()
        };
        let mut this = EmbreeScene {
            device,
            scene,
            errors,
            _vertices: geometry
                .positions
                .iter()
                .map(|p| [p.x, p.y, p.z, 0.0])
                .collect(),
            _indices: if geometry.cutouts.is_empty() {
                geometry.triangles.clone()
            } else {
                indices(&opaque_triangles)
            },
            _cutout_indices: indices(&cutout_triangles),
            group_first: Vec::new(),
            opaque_triangles,
            group_starts: geometry.group_starts.clone(),
            filter: Box::new(CutoutFilter {
                triangles: cutout_triangles,
                cutouts: geometry.cutouts.clone(),
            }),
            _spheres: embree_spheres
                .iter()
                .map(|s| [s.center.x, s.center.y, s.center.z, s.radius])
                .collect(),
            spheres: embree_spheres,
            direct_spheres,
            triangle_geometry: sys::RTC_INVALID_GEOMETRY_ID,
            cutout_geometry: sys::RTC_INVALID_GEOMETRY_ID,
            sphere_geometry: sys::RTC_INVALID_GEOMETRY_ID,
        };
        this.check()?;
        check_hit_layout(device)?;
        this.check()?;
        // SAFETY: `scene` is valid.
        unsafe {
            sys::rtcSetSceneBuildQuality(scene, sys::RTCBuildQuality_RTC_BUILD_QUALITY_MEDIUM)
        };
        if geometry.cutouts.is_empty() {
            for group in geometry.groups() {
                let triangles = &this._indices[group.start as usize..group.end as usize];
                let id = this.attach_triangles(triangles, false)?;
                if id as usize != this.group_first.len() {
                    return Err(AccelError::Embree {
                        code: 0,
                        message: format!("group {} got geometry id {id}", this.group_first.len()),
                    });
                }
                this.group_first.push(group.start);
            }
        } else if !this._indices.is_empty() {
            this.triangle_geometry = this.attach_triangles(&this._indices, false)?;
        }
        if !this._cutout_indices.is_empty() {
            // SAFETY: `device` is valid.
            let supported = unsafe {
                sys::rtcGetDeviceProperty(
                    device,
                    sys::RTCDeviceProperty_RTC_DEVICE_PROPERTY_FILTER_FUNCTION_SUPPORTED,
                )
            };
            if supported == 0 {
                return Err(AccelError::Embree {
                    code: 0,
                    message: "this Embree library was built without filter functions, which \
                              alpha cut-outs need; use the Rust BVH"
                        .into(),
                });
            }
            this.cutout_geometry = this.attach_triangles(&this._cutout_indices, true)?;
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
                None,
            )?;
        }
        // SAFETY: `scene` is valid and every attached buffer is alive in `this`.
        unsafe { sys::rtcCommitScene(scene) };
        this.check()?;
        Ok(this)
    }

    /// A triangle geometry over the shared vertices and `indices` (a buffer of `self`), with
    /// the cut-out filter functions when `cut_out`; returns its id.
    fn attach_triangles(&self, indices: &[[u32; 3]], cut_out: bool) -> Result<u32, AccelError> {
        let filter = cut_out.then_some(&*self.filter);
        self.attach(
            sys::RTCGeometryType_RTC_GEOMETRY_TYPE_TRIANGLE,
            &[
                (
                    sys::RTCBufferType_RTC_BUFFER_TYPE_VERTEX,
                    sys::RTCFormat_RTC_FORMAT_FLOAT3,
                    self._vertices.as_ptr().cast(),
                    16,
                    self._vertices.len(),
                ),
                (
                    sys::RTCBufferType_RTC_BUFFER_TYPE_INDEX,
                    sys::RTCFormat_RTC_FORMAT_UINT3,
                    indices.as_ptr().cast(),
                    12,
                    indices.len(),
                ),
            ],
            filter,
        )
    }

    /// Creates a geometry over shared buffers `(type, format, pointer, stride, count)`, with
    /// the cut-out filter functions reading `filter` where given, commits and attaches it;
    /// returns its id.
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
        filter: Option<&CutoutFilter>,
    ) -> Result<u32, AccelError> {
        // SAFETY: `device` is valid.
        let geometry = unsafe { sys::rtcNewGeometry(self.device, kind) };
        self.check()?;
        if let Some(filter) = filter {
            // SAFETY: `geometry` is valid; `filter` is boxed in `self` and outlives the scene,
            // and the filter functions only read it.
            unsafe {
                sys::rtcSetGeometryUserData(geometry, filter as *const CutoutFilter as *mut c_void);
                sys::rtcSetGeometryIntersectFilterFunction(geometry, Some(cutout_filter));
                sys::rtcSetGeometryOccludedFilterFunction(geometry, Some(cutout_filter));
            }
        }
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

    /// The [`Hit`] of Embree's answer for `ray`. Inlined for the common case, a triangle of a
    /// group's geometry; the rest (scenes with cut-outs, spheres) kept out of line: this runs
    /// once per ray and lane.
    #[inline(always)]
    fn hit(&self, h: RawHit, ray: &Ray) -> Option<Hit> {
        match self.group_first.get(h.geom_id as usize) {
            Some(&first) => Some(h.triangle(first + h.prim_id, h.geom_id)),
            None => self.other_hit(h, ray),
        }
    }

    /// [`EmbreeScene::hit`] on the opaque or cut-out geometry of a scene with cut-outs, or on
    /// a sphere.
    #[inline(never)]
    fn other_hit(&self, h: RawHit, ray: &Ray) -> Option<Hit> {
        let triangle = |i: u32| Some(h.triangle(i, group_of(&self.group_starts, i)));
        if h.geom_id == self.triangle_geometry {
            triangle(self.opaque_triangles[h.prim_id as usize])
        } else if h.geom_id == self.cutout_geometry {
            triangle(self.filter.triangles[h.prim_id as usize])
        } else if h.geom_id == self.sphere_geometry {
            Some(self.sphere_hit(h.prim_id, h.t, ray))
        } else {
            None
        }
    }

    /// The nearest of the directly tested spheres `ray` meets, as its index and `t`.
    #[inline]
    fn nearest_direct_sphere(&self, ray: &Ray) -> Option<(u32, f32)> {
        let mut nearest = None;
        let mut tmax = ray.tmax;
        for (i, sphere) in self.direct_spheres.iter().enumerate() {
            if let Some(t) = sphere.first_hit(ray, tmax) {
                nearest = Some((i as u32, t));
                tmax = t;
            }
        }
        nearest
    }

    /// Whether `ray` meets any of the directly tested spheres.
    #[inline]
    fn direct_spheres_occlude(&self, ray: &Ray) -> bool {
        self.direct_spheres
            .iter()
            .any(|sphere| sphere.first_hit(ray, ray.tmax).is_some())
    }

    #[inline]
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
        sphere.hit(prim_id, ray, t)
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

impl RawHit {
    /// The hit on triangle `triangle` of group `group`, with Embree's Ng (same winding as the
    /// [`Hit`] contract) rather than one recomputed from the vertices: reading those again is
    /// a cache miss on large meshes.
    #[inline(always)]
    fn triangle(&self, triangle: u32, group: u32) -> Hit {
        Hit {
            t: self.t,
            primitive: Primitive::Triangle(triangle),
            group,
            u: self.u,
            v: self.v,
            ng: self.ng,
        }
    }
}

fn rtc_ray(ray: &Ray) -> sys::RTCRay {
    sys::RTCRay {
        org_x: narrow(&ray.origin.x),
        org_y: narrow(&ray.origin.y),
        org_z: narrow(&ray.origin.z),
        tnear: narrow(&ray.tmin),
        dir_x: narrow(&ray.dir.x),
        dir_y: narrow(&ray.dir.y),
        dir_z: narrow(&ray.dir.z),
        time: 0.0,
        tfar: narrow(&ray.tmax),
        // Debian's Embree is built with ray masks: a zero mask misses everything.
        mask: u32::MAX,
        id: 0,
        flags: 0,
    }
}

/// `*x` read by a load of its own width. The ray and Embree's answer were stored moments before
/// they are read, field by field or in wider pieces; a load the compiler merges across two
/// neighbouring fields spans two stores, cannot take its value from the store buffer, and waits
/// for both to reach the cache (a store-forwarding stall, on every ray). A load within one
/// store is forwarded.
#[inline(always)]
fn narrow<T: Copy>(x: &T) -> T {
    // SAFETY: `x` is a reference: the pointer is valid, aligned and points to an initialised T.
    unsafe { std::ptr::read_volatile(x) }
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

fn empty_hit8() -> sys::RTCHit8 {
    sys::RTCHit8 {
        geomID: [sys::RTC_INVALID_GEOMETRY_ID; PACKET],
        instID: [[sys::RTC_INVALID_GEOMETRY_ID; PACKET]],
        ..Default::default()
    }
}

/// The ray queries in the API of the Embree found at build time. Both versions are asked for
/// the same traversal: incoherent rays, the geometries' own filter functions (cut-outs) and
/// none of the query's, no instancing.
#[cfg(embree3)]
mod query {
    use super::{sys, ValidMask};

    /// `rtcInitIntersectContext`, an inline header function, re-implemented.
    #[inline]
    fn context() -> sys::RTCIntersectContext {
        sys::RTCIntersectContext {
            flags: sys::RTCIntersectContextFlags_RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT,
            filter: None,
            instID: [sys::RTC_INVALID_GEOMETRY_ID],
        }
    }

    /// # Safety
    /// `scene` is a committed scene.
    #[inline]
    pub unsafe fn intersect1(scene: sys::RTCScene, rayhit: &mut sys::RTCRayHit) {
        let mut context = context();
        // SAFETY: the caller's scene is committed; context and rayhit live for the call.
        unsafe { sys::rtcIntersect1(scene, &mut context, rayhit) }
    }

    /// # Safety
    /// `scene` is a committed scene.
    #[inline]
    pub unsafe fn occluded1(scene: sys::RTCScene, ray: &mut sys::RTCRay) {
        let mut context = context();
        // SAFETY: as for `intersect1`.
        unsafe { sys::rtcOccluded1(scene, &mut context, ray) }
    }

    /// # Safety
    /// `scene` is a committed scene.
    #[inline]
    pub unsafe fn intersect8(
        valid: &ValidMask,
        scene: sys::RTCScene,
        rayhit: &mut sys::RTCRayHit8,
    ) {
        let mut context = context();
        // SAFETY: `valid` and `rayhit` are 32-byte aligned by their types' repr and live for the
        // call; the caller's scene is committed.
        unsafe { sys::rtcIntersect8(valid.0.as_ptr(), scene, &mut context, rayhit) }
    }

    /// # Safety
    /// `scene` is a committed scene.
    #[inline]
    pub unsafe fn occluded8(valid: &ValidMask, scene: sys::RTCScene, ray: &mut sys::RTCRay8) {
        let mut context = context();
        // SAFETY: as for `intersect8`.
        unsafe { sys::rtcOccluded8(valid.0.as_ptr(), scene, &mut context, ray) }
    }
}

/// The ray queries in the API of the Embree found at build time. Both versions are asked for
/// the same traversal: incoherent rays, the geometries' own filter functions (cut-outs) and
/// none of the query's, no instancing.
#[cfg(embree4)]
mod query {
    use super::{sys, ValidMask};
    use std::ptr::null_mut;

    /// The features vmerge's scenes have. The mask is for SYCL, which compiles traversal for the
    /// features named only; naming exactly these keeps it right there too.
    const FEATURES: sys::RTCFeatureFlags = sys::RTCFeatureFlags_RTC_FEATURE_FLAG_TRIANGLE
        | sys::RTCFeatureFlags_RTC_FEATURE_FLAG_SPHERE_POINT
        | sys::RTCFeatureFlags_RTC_FEATURE_FLAG_FILTER_FUNCTION_IN_GEOMETRY;

    // `rtcInitIntersectArguments` / `rtcInitOccludedArguments`, inline header functions,
    // re-implemented with the feature mask narrowed. Their null ray query context makes Embree
    // initialise its own (`rtcInitRayQueryContext`) with the layout the library was built
    // with; nothing here needs the instance stack a context carries.

    #[inline]
    #[allow(
        clippy::needless_update,
        reason = "minWidthDistanceFactor exists where RTC_MIN_WIDTH is set"
    )]
    fn intersect_arguments() -> sys::RTCIntersectArguments {
        sys::RTCIntersectArguments {
            flags: sys::RTCRayQueryFlags_RTC_RAY_QUERY_FLAG_INCOHERENT,
            feature_mask: FEATURES,
            context: null_mut(),
            filter: None,
            intersect: None,
            ..Default::default()
        }
    }

    #[inline]
    #[allow(
        clippy::needless_update,
        reason = "minWidthDistanceFactor exists where RTC_MIN_WIDTH is set"
    )]
    fn occluded_arguments() -> sys::RTCOccludedArguments {
        sys::RTCOccludedArguments {
            flags: sys::RTCRayQueryFlags_RTC_RAY_QUERY_FLAG_INCOHERENT,
            feature_mask: FEATURES,
            context: null_mut(),
            filter: None,
            occluded: None,
            ..Default::default()
        }
    }

    /// # Safety
    /// `scene` is a committed scene.
    #[inline]
    pub unsafe fn intersect1(scene: sys::RTCScene, rayhit: &mut sys::RTCRayHit) {
        let mut args = intersect_arguments();
        // SAFETY: the caller's scene is committed; rayhit and args live for the call.
        unsafe { sys::rtcIntersect1(scene, rayhit, &mut args) }
    }

    /// # Safety
    /// `scene` is a committed scene.
    #[inline]
    pub unsafe fn occluded1(scene: sys::RTCScene, ray: &mut sys::RTCRay) {
        let mut args = occluded_arguments();
        // SAFETY: as for `intersect1`.
        unsafe { sys::rtcOccluded1(scene, ray, &mut args) }
    }

    /// # Safety
    /// `scene` is a committed scene.
    #[inline]
    pub unsafe fn intersect8(
        valid: &ValidMask,
        scene: sys::RTCScene,
        rayhit: &mut sys::RTCRayHit8,
    ) {
        let mut args = intersect_arguments();
        // SAFETY: `valid` and `rayhit` are 32-byte aligned by their types' repr and live for the
        // call, as do the arguments; the caller's scene is committed.
        unsafe { sys::rtcIntersect8(valid.0.as_ptr(), scene, rayhit, &mut args) }
    }

    /// # Safety
    /// `scene` is a committed scene.
    #[inline]
    pub unsafe fn occluded8(valid: &ValidMask, scene: sys::RTCScene, ray: &mut sys::RTCRay8) {
        let mut args = occluded_arguments();
        // SAFETY: as for `intersect8`.
        unsafe { sys::rtcOccluded8(valid.0.as_ptr(), scene, ray, &mut args) }
    }
}

/// A query's answer with room after it, to see whether Embree writes past its end.
#[repr(C)]
struct WithSpare<T> {
    answer: T,
    spare: [u32; 32],
}

const UNTOUCHED: u32 = 0x5a5a_5a5a;

/// Embree writes a hit's instance ids in as many levels as the library was built with, and
/// Embree 4 also their primitive ids where built with instance arrays; a header configured
/// otherwise (`rtcore_config.h`) makes `RTCHit` shorter than what Embree writes. One ray and
/// one packet at a one-triangle scene, with spare words after their answers, tell.
fn check_hit_layout(device: sys::RTCDevice) -> Result<(), AccelError> {
    let vertices: [[f32; 4]; 3] = [[0.0; 4], [1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]];
    let indices: [[u32; 3]; 1] = [[0, 1, 2]];
    // SAFETY: `device` is valid; the buffers outlive the scene, released at the end of this
    // function, and vertices are 16-byte items for Embree's 16-byte reads.
    let scene = unsafe {
        let scene = sys::rtcNewScene(device);
        let mesh = sys::rtcNewGeometry(device, sys::RTCGeometryType_RTC_GEOMETRY_TYPE_TRIANGLE);
        sys::rtcSetSharedGeometryBuffer(
            mesh,
            sys::RTCBufferType_RTC_BUFFER_TYPE_VERTEX,
            0,
            sys::RTCFormat_RTC_FORMAT_FLOAT3,
            vertices.as_ptr().cast(),
            0,
            16,
            vertices.len(),
        );
        sys::rtcSetSharedGeometryBuffer(
            mesh,
            sys::RTCBufferType_RTC_BUFFER_TYPE_INDEX,
            0,
            sys::RTCFormat_RTC_FORMAT_UINT3,
            indices.as_ptr().cast(),
            0,
            12,
            indices.len(),
        );
        sys::rtcCommitGeometry(mesh);
        sys::rtcAttachGeometry(scene, mesh);
        sys::rtcReleaseGeometry(mesh);
        sys::rtcCommitScene(scene);
        scene
    };
    let ray = Ray::new(Vec3::new(0.25, 0.25, -1.0), Vec3::Z);
    let mut one = WithSpare {
        answer: sys::RTCRayHit {
            ray: rtc_ray(&ray),
            hit: empty_hit(),
        },
        spare: [UNTOUCHED; 32],
    };
    let (valid, ray8) = packet_rays(&[ray; PACKET], 0xff);
    let mut eight = WithSpare {
        answer: sys::RTCRayHit8 {
            ray: ray8,
            hit: empty_hit8(),
        },
        spare: [UNTOUCHED; 32],
    };
    // SAFETY: the scene is committed (or empty after an error, which Embree answers with
    // misses); it is released here and never used again. Anything Embree writes past an
    // answer lands in its spare words.
    unsafe {
        query::intersect1(scene, &mut one.answer);
        query::intersect8(&valid, scene, &mut eight.answer);
        sys::rtcReleaseScene(scene);
    }
    let overrun = |spare: &[u32]| {
        spare
            .iter()
            .rposition(|&w| w != UNTOUCHED)
            .map_or(0, |i| 4 * (i + 1))
    };
    let (single, packet) = (overrun(&one.spare), overrun(&eight.spare));
    let hits = one.answer.hit.geomID == 0 && eight.answer.hit.geomID.iter().all(|&g| g == 0);
    if single == 0 && packet == 0 && hits {
        return Ok(());
    }
    Err(AccelError::Embree {
        code: 0,
        message: format!(
            "the Embree library does not match the header vmerge was built with: it wrote \
             {single} bytes past RTCRayHit and {packet} past RTCRayHit8{}; rebuild against the \
             library's own headers (rtcore_config.h: RTC_MAX_INSTANCE_LEVEL_COUNT, \
             EMBREE_GEOMETRY_INSTANCE_ARRAY)",
            if hits {
                ""
            } else {
                ", and missed a triangle in front of the rays"
            }
        ),
    })
}

/// Embree reads vertices through the indices unchecked: an index beyond the vertices given
/// would be read out of bounds.
fn check_indices(geometry: &Geometry) -> Result<(), AccelError> {
    match geometry
        .triangles
        .iter()
        .position(|t| t.iter().any(|&v| v as usize >= geometry.positions.len()))
    {
        Some(i) => Err(AccelError::InvalidGeometry(format!(
            "triangle {i} indexes a vertex beyond the {} given",
            geometry.positions.len()
        ))),
        None => Ok(()),
    }
}

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
        let sphere = self.nearest_direct_sphere(ray);
        let mut rayhit = sys::RTCRayHit {
            ray: rtc_ray(ray),
            hit: empty_hit(),
        };
        if let Some((_, t)) = sphere {
            rayhit.ray.tfar = t;
        }
        // SAFETY: the scene is committed.
        unsafe { query::intersect1(self.scene, &mut rayhit) };
        let h = &rayhit.hit;
        if h.geomID == sys::RTC_INVALID_GEOMETRY_ID {
            return sphere.map(|(i, t)| self.direct_spheres[i as usize].hit(i, ray, t));
        }
        self.hit(
            RawHit {
                geom_id: narrow(&h.geomID),
                prim_id: narrow(&h.primID),
                t: narrow(&rayhit.ray.tfar),
                u: narrow(&h.u),
                v: narrow(&h.v),
                ng: Vec3::new(narrow(&h.Ng_x), narrow(&h.Ng_y), narrow(&h.Ng_z)),
            },
            ray,
        )
    }

    fn occluded(&self, ray: &Ray) -> bool {
        ensure_flush_denormals();
        if self.direct_spheres_occlude(ray) {
            return true;
        }
        let mut r = rtc_ray(ray);
        // SAFETY: the scene is committed.
        unsafe { query::occluded1(self.scene, &mut r) };
        // A hit sets tfar to -inf; a miss leaves it unchanged.
        r.tfar == f32::NEG_INFINITY
    }

    fn intersect8(&self, rays: &[Ray; PACKET], active: u8, hits: &mut [Option<Hit>; PACKET]) {
        ensure_flush_denormals();
        let (valid, ray8) = packet_rays(rays, active);
        let mut rayhit = sys::RTCRayHit8 {
            ray: ray8,
            hit: empty_hit8(),
        };
        let mut spheres = [None; PACKET];
        if !self.direct_spheres.is_empty() {
            for (i, (ray, sphere)) in rays.iter().zip(&mut spheres).enumerate() {
                if active & (1 << i) != 0 {
                    *sphere = self.nearest_direct_sphere(ray);
                    if let Some((_, t)) = *sphere {
                        rayhit.ray.tfar[i] = t;
                    }
                }
            }
        }
        // SAFETY: the scene is committed.
        unsafe { query::intersect8(&valid, self.scene, &mut rayhit) };
        for (i, (ray, out)) in rays.iter().zip(hits.iter_mut()).enumerate() {
            let h = &rayhit.hit;
            if active & (1 << i) == 0 {
                *out = None;
                continue;
            }
            *out = if h.geomID[i] == sys::RTC_INVALID_GEOMETRY_ID {
                spheres[i].map(|(k, t)| self.direct_spheres[k as usize].hit(k, ray, t))
            } else {
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
            };
        }
    }

    fn occluded8(&self, rays: &[Ray; PACKET], active: u8) -> u8 {
        ensure_flush_denormals();
        // Lanes a sphere already blocks leave the packet before Embree sees it.
        let by_spheres = (0..PACKET)
            .filter(|&i| active & (1 << i) != 0 && self.direct_spheres_occlude(&rays[i]))
            .fold(0u8, |mask, i| mask | (1 << i));
        let rest = active & !by_spheres;
        if rest == 0 {
            return by_spheres;
        }
        let (valid, mut ray8) = packet_rays(rays, rest);
        // SAFETY: the scene is committed.
        unsafe { query::occluded8(&valid, self.scene, &mut ray8) };
        (0..PACKET)
            .filter(|&i| rest & (1 << i) != 0 && ray8.tfar[i] == f32::NEG_INFINITY)
            .fold(by_spheres, |mask, i| mask | (1 << i))
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
        check_indices(geometry)?;
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
        check_hit_layout(device)?;
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
        let mut hits = 0;
        for ray in rays {
            let mut rayhit = sys::RTCRayHit {
                ray: rtc_ray(ray),
                hit: empty_hit(),
            };
            // SAFETY: the scene is committed.
            unsafe { query::intersect1(self.scene, &mut rayhit) };
            hits += (rayhit.hit.geomID != sys::RTC_INVALID_GEOMETRY_ID) as u64;
        }
        hits
    }

    /// Occlusion of `rays` through `rtcOccluded1`; returns how many are occluded.
    pub fn occluded1(&self, rays: &[Ray]) -> u64 {
        ensure_flush_denormals();
        let mut occluded = 0;
        for ray in rays {
            let mut r = rtc_ray(ray);
            // SAFETY: the scene is committed.
            unsafe { query::occluded1(self.scene, &mut r) };
            occluded += (r.tfar == f32::NEG_INFINITY) as u64;
        }
        occluded
    }

    /// Closest hits of `rays`, 8 at a time through `rtcIntersect8` (a partial last packet is
    /// left out); returns how many hit.
    pub fn intersect8(&self, rays: &[Ray]) -> u64 {
        ensure_flush_denormals();
        let mut hits = 0;
        for chunk in rays.chunks_exact(PACKET) {
            let Ok(packet) = <&[Ray; PACKET]>::try_from(chunk) else {
                continue;
            };
            let (valid, ray) = packet_rays(packet, 0xff);
            let mut rayhit = sys::RTCRayHit8 {
                ray,
                hit: empty_hit8(),
            };
            // SAFETY: the scene is committed.
            unsafe { query::intersect8(&valid, self.scene, &mut rayhit) };
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
        let mut occluded = 0;
        for chunk in rays.chunks_exact(PACKET) {
            let Ok(packet) = <&[Ray; PACKET]>::try_from(chunk) else {
                continue;
            };
            let (valid, mut ray) = packet_rays(packet, 0xff);
            // SAFETY: the scene is committed.
            unsafe { query::occluded8(&valid, self.scene, &mut ray) };
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
