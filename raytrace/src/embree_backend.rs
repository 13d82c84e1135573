//! The Embree 4 backend (feature `embree`), through the raw `embree4-sys` bindings: the
//! `embree4-rs` wrapper exposes neither filter nor user-geometry callbacks.
//!
//! Triangles: an Embree triangle geometry; every hit Embree finds reaches an intersection
//! filter passed per query (`RTCIntersectArguments`; it runs only with the scene flag
//! `FILTER_FUNCTION_IN_ARGUMENTS` and the query flag `INVOKE_ARGUMENT_FILTER` or the geometry
//! enabled for it: all three are set), which hands the primitive to the caller's closure (the
//! exact watertight test and the k-buffer) and rejects the hit (`valid = 0`) so traversal goes
//! on. Once the k-buffer is full, a hit beyond the cull distance is accepted instead: Embree
//! then shortens the ray to it, which culls the rest of the far geometry without dropping
//! anything the k-buffer could still take. Boxes: a user geometry whose intersect callback
//! hands the primitive to the closure and shortens the ray (`tfar`) to the cull distance.
//!
//! Embree's edge rule differs from the watertight test on exact edges: on a ray through an edge
//! shared by two triangles, each may pick a different one of the pair. A triangle Embree
//! reports is therefore passed as `reported`, and the mesh mode counts it even when its own
//! test gives the hit to the neighbour (which Embree then never reports); the group key counts
//! the fan once either way. Backends thus agree except for rays within f32 rounding of an
//! outer fan edge. Scenes are built with
//! `RTC_SCENE_FLAG_ROBUST` (no traversal shortcuts that lose edge hits).

use std::ffi::c_void;
use std::sync::OnceLock;

use embree4_sys as sys;
use glam::Vec3;

use crate::backend::{Accel, BuildPreset};
use crate::error::{Result, TraceError};

struct Device(sys::RTCDevice);
// SAFETY: an Embree device is thread-safe (Embree's API contract: device calls may be made
// from any thread); the handle is never released, so it stays valid for the process.
unsafe impl Send for Device {}
// SAFETY: as for `Send`; shared references only pass the handle to thread-safe API calls.
unsafe impl Sync for Device {}

fn device() -> Result<&'static Device> {
    static DEV: OnceLock<std::result::Result<Device, String>> = OnceLock::new();
    DEV.get_or_init(|| {
        // A null config: embree4-rs passes configs without a NUL terminator.
        // SAFETY: a null config pointer is allowed (Embree's defaults); no other argument.
        let d = unsafe { sys::rtcNewDevice(std::ptr::null()) };
        if d.is_null() {
            // SAFETY: a null device asks for the error of the failed device creation, which
            // Embree documents as allowed.
            let e = unsafe { sys::rtcGetDeviceError(std::ptr::null_mut()) };
            Err(format!("Embree device creation failed: {e:?}"))
        } else {
            Ok(Device(d))
        }
    })
    .as_ref()
    .map_err(|e| TraceError::Backend(e.clone()))
}

fn check(dev: &Device, what: &str) -> Result<()> {
    // SAFETY: `dev.0` is a live device (created by `device()`, never released).
    let e = unsafe { sys::rtcGetDeviceError(dev.0) };
    if e == sys::RTCError::NONE {
        Ok(())
    } else {
        Err(TraceError::Backend(format!("Embree: {what}: {e:?}")))
    }
}

fn quality(p: BuildPreset) -> sys::RTCBuildQuality {
    match p {
        BuildPreset::Fastest | BuildPreset::VeryFast => sys::RTCBuildQuality::LOW,
        BuildPreset::Fast | BuildPreset::Medium => sys::RTCBuildQuality::MEDIUM,
    }
}

/// The query context Embree passes to callbacks; starts with `RTCRayQueryContext` as Embree
/// requires, followed by the caller's closure and the current cull distance.
#[repr(C)]
struct Ctx {
    base: sys::RTCRayQueryContext,
    visit: *mut &'static mut dyn FnMut(u32, bool, &mut f32),
    cull: f32,
}

unsafe extern "C" fn tri_filter(args: *const sys::RTCFilterFunctionNArguments) {
    // SAFETY: Embree passes valid pointers for N = 1 queries (rtcIntersect1): `ray` and `hit`
    // point to an RTCRay and an RTCHit, and `context` is the one we passed in.
    unsafe {
        let a = &*args;
        let ctx = &mut *(a.context as *mut Ctx);
        let ray = &*(a.ray as *const sys::RTCRay);
        let hit = &*(a.hit as *const sys::RTCHit);
        let visit = &mut *ctx.visit;
        visit(hit.primID, true, &mut ctx.cull);
        // Beyond the cull distance (with margin): accept, so Embree shortens the ray there.
        let far = ray.tfar > ctx.cull * (1.0 + 1e-5) + f32::MIN_POSITIVE;
        if !far {
            *a.valid = 0;
        }
    }
}

unsafe extern "C" fn box_bounds(args: *const sys::RTCBoundsFunctionArguments) {
    // SAFETY: the user pointer is the data of the boxes vector owned by the accel (a heap
    // buffer that does not move with the accel), alive while the scene is; primID < count.
    unsafe {
        let a = &*args;
        let (lo, hi) = *(a.geometryUserPtr as *const (Vec3, Vec3)).add(a.primID as usize);
        let b = &mut *a.bounds_o;
        b.lower_x = lo.x;
        b.lower_y = lo.y;
        b.lower_z = lo.z;
        b.upper_x = hi.x;
        b.upper_y = hi.y;
        b.upper_z = hi.z;
    }
}

unsafe extern "C" fn box_intersect(args: *const sys::RTCIntersectFunctionNArguments) {
    // SAFETY: as in `tri_filter`; for rtcIntersect1, `rayhit` is an RTCRayHit.
    unsafe {
        let a = &*args;
        if *a.valid == 0 {
            return;
        }
        let ctx = &mut *(a.context as *mut Ctx);
        let rh = &mut *(a.rayhit as *mut sys::RTCRayHit);
        let visit = &mut *ctx.visit;
        visit(a.primID, false, &mut ctx.cull);
        let cull = ctx.cull * (1.0 + 1e-5) + f32::MIN_POSITIVE;
        if cull < rh.ray.tfar {
            rh.ray.tfar = cull;
        }
    }
}

/// An Embree scene over triangles or boxes.
pub struct EmbreeAccel {
    scene: sys::RTCScene,
    /// Owned box data referenced by the user geometry's callbacks.
    _boxes: Option<Vec<(Vec3, Vec3)>>,
    triangles: bool,
}

// SAFETY: the scene handle is owned by this value (released once, in Drop), and the box
// data its callbacks read moves with it (a Vec's heap buffer does not move).
unsafe impl Send for EmbreeAccel {}
// SAFETY: a committed Embree scene may be queried from many threads at once (Embree's API
// contract); `&self` methods only query, and the box data is read-only after the build.
unsafe impl Sync for EmbreeAccel {}

impl Drop for EmbreeAccel {
    fn drop(&mut self) {
        // SAFETY: `self.scene` is the live scene this value owns; it is released once, here.
        unsafe { sys::rtcReleaseScene(self.scene) };
    }
}

fn new_scene(dev: &Device, preset: BuildPreset) -> Result<sys::RTCScene> {
    // SAFETY: `dev.0` is a live device.
    let scene = unsafe { sys::rtcNewScene(dev.0) };
    if scene.is_null() {
        check(dev, "rtcNewScene")?;
        return Err(TraceError::Backend(
            "Embree: rtcNewScene returned null".into(),
        ));
    }
    // SAFETY: `scene` was just created and checked non-null; flags and quality are valid
    // enum values.
    unsafe {
        sys::rtcSetSceneFlags(
            scene,
            sys::RTCSceneFlags::ROBUST | sys::RTCSceneFlags::FILTER_FUNCTION_IN_ARGUMENTS,
        );
        sys::rtcSetSceneBuildQuality(scene, quality(preset));
    }
    check(dev, "scene setup")?;
    Ok(scene)
}

impl EmbreeAccel {
    pub fn triangles(preset: BuildPreset, verts: &[Vec3], tris: &[[u32; 3]]) -> Result<Self> {
        let dev = device()?;
        let scene = new_scene(dev, preset)?;
        let out = EmbreeAccel {
            scene,
            _boxes: None,
            triangles: true,
        };
        // SAFETY: `dev.0` is live and `scene` non-null (owned by `out`, released on every
        // return). Each buffer is allocated by Embree for `len` items of 12 bytes (checked
        // non-null before writing), so the copies below write `len × 3` f32/u32 in bounds;
        // `Vec3` and `[u32; 3]` are three packed 4-byte values. The geometry is released
        // after attaching (the scene keeps its own reference).
        unsafe {
            let g = sys::rtcNewGeometry(dev.0, sys::RTCGeometryType::TRIANGLE);
            check(dev, "rtcNewGeometry")?;
            let vb = sys::rtcSetNewGeometryBuffer(
                g,
                sys::RTCBufferType::VERTEX,
                0,
                sys::RTCFormat::FLOAT3,
                12,
                verts.len(),
            ) as *mut f32;
            let ib = sys::rtcSetNewGeometryBuffer(
                g,
                sys::RTCBufferType::INDEX,
                0,
                sys::RTCFormat::UINT3,
                12,
                tris.len(),
            ) as *mut u32;
            check(dev, "geometry buffers")?;
            if vb.is_null() || ib.is_null() {
                sys::rtcReleaseGeometry(g);
                return Err(TraceError::Backend(
                    "Embree: geometry buffer allocation failed".into(),
                ));
            }
            // Embree allocated `len × 12` bytes for each buffer (see the SAFETY note above).
            std::ptr::copy_nonoverlapping(verts.as_ptr() as *const f32, vb, verts.len() * 3);
            std::ptr::copy_nonoverlapping(tris.as_ptr() as *const u32, ib, tris.len() * 3);
            sys::rtcSetGeometryEnableFilterFunctionFromArguments(g, true);
            sys::rtcCommitGeometry(g);
            sys::rtcAttachGeometry(scene, g);
            sys::rtcReleaseGeometry(g);
            sys::rtcCommitScene(scene);
        }
        check(dev, "scene build")?;
        Ok(out)
    }

    pub fn boxes(preset: BuildPreset, boxes: &[(Vec3, Vec3)]) -> Result<Self> {
        let dev = device()?;
        let scene = new_scene(dev, preset)?;
        let data = boxes.to_vec();
        // SAFETY: `dev.0` is live and `scene` non-null. The user pointer is `data`'s heap
        // buffer, which the returned accel owns (`_boxes`) for as long as the scene exists, and
        // `box_bounds`/`box_intersect` read at most `boxes.len()` entries (the primitive count).
        unsafe {
            let g = sys::rtcNewGeometry(dev.0, sys::RTCGeometryType::USER);
            check(dev, "rtcNewGeometry")?;
            sys::rtcSetGeometryUserPrimitiveCount(g, boxes.len() as u32);
            let ptr = data.as_ptr() as *mut c_void;
            sys::rtcSetGeometryUserData(g, ptr);
            sys::rtcSetGeometryBoundsFunction(g, Some(box_bounds), ptr);
            sys::rtcSetGeometryIntersectFunction(g, Some(box_intersect));
            sys::rtcCommitGeometry(g);
            sys::rtcAttachGeometry(scene, g);
            sys::rtcReleaseGeometry(g);
            sys::rtcCommitScene(scene);
        }
        check(dev, "scene build")?;
        Ok(EmbreeAccel {
            scene,
            _boxes: Some(data),
            triangles: false,
        })
    }
}

impl Accel for EmbreeAccel {
    fn traverse(
        &self,
        origin: Vec3,
        dir: Vec3,
        tmax: f32,
        visit: &mut dyn FnMut(u32, bool, &mut f32),
    ) {
        self.query(origin, dir, 0.0, tmax, visit);
    }

    fn traverse_slots(
        &self,
        origin: Vec3,
        dir: Vec3,
        tmin: f32,
        tmax: f32,
        visit: &mut dyn FnMut(u32, bool, &mut f32),
    ) {
        // Start just before `tmin` (1e-5 relative margin) so a hit at exactly `tmin` is kept.
        let tnear = if tmin > 0.0 && tmin.is_finite() {
            tmin * (1.0 - 1e-5)
        } else {
            0.0
        };
        self.query(origin, dir, tnear, tmax, visit);
    }
}

impl EmbreeAccel {
    fn query(
        &self,
        origin: Vec3,
        dir: Vec3,
        tnear: f32,
        tmax: f32,
        visit: &mut dyn FnMut(u32, bool, &mut f32),
    ) {
        // SAFETY: the closure outlives the query; the 'static is only to store it in the
        // context struct and is never used beyond this call.
        let mut vref: &mut dyn FnMut(u32, bool, &mut f32) = visit;
        let vptr = &mut vref as *mut &mut dyn FnMut(u32, bool, &mut f32)
            as *mut &'static mut dyn FnMut(u32, bool, &mut f32);
        let mut ctx = Ctx {
            base: sys::RTCRayQueryContext { instID: [u32::MAX] },
            visit: vptr,
            cull: tmax,
        };
        let mut args = sys::RTCIntersectArguments {
            // The argument filter runs only for geometries that enable it, or for all with
            // this flag; both are set.
            flags: sys::RTCRayQueryFlags::INVOKE_ARGUMENT_FILTER,
            feature_mask: sys::RTCFeatureFlags(u32::MAX),
            context: &mut ctx.base as *mut sys::RTCRayQueryContext,
            filter: if self.triangles {
                Some(tri_filter)
            } else {
                None
            },
            intersect: None,
        };
        let mut rh = sys::RTCRayHit {
            ray: sys::RTCRay {
                org_x: origin.x,
                org_y: origin.y,
                org_z: origin.z,
                tnear,
                dir_x: dir.x,
                dir_y: dir.y,
                dir_z: dir.z,
                time: 0.0,
                tfar: tmax,
                mask: u32::MAX,
                id: 0,
                flags: 0,
            },
            hit: sys::RTCHit {
                Ng_x: 0.0,
                Ng_y: 0.0,
                Ng_z: 0.0,
                u: 0.0,
                v: 0.0,
                primID: u32::MAX,
                geomID: u32::MAX,
                instID: [u32::MAX],
            },
        };
        // SAFETY: `self.scene` is a committed live scene; `rh`, `args` and `ctx` (which
        // `args.context` points to) live on this stack frame for the whole call, and the
        // filter/intersect callbacks read `ctx.visit` only during it.
        unsafe { sys::rtcIntersect1(self.scene, &mut rh, &mut args) };
    }
}
