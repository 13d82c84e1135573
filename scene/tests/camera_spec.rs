//! Camera selection: specs and lists resolved against a scene, the size limits, and the
//! orbit rig's one-camera path against the whole rig.

use glam::{DVec3, Quat, Vec3};
use splatbridge_scene::camera::{save_cameras_json, Camera, OrbitRig};
use splatbridge_scene::camera_spec::{
    parse_camera_list, CameraListItem, CameraRequest, CameraSource, CameraSpec,
    DEFAULT_PIXEL_BUDGET, MAX_IMAGE_SIDE, MAX_ORBIT_CAMERAS,
};
use splatbridge_scene::GaussianCloud;

fn cloud() -> GaussianCloud {
    let mut c = GaussianCloud::with_capacity(0, 64);
    for i in 0..64 {
        let p = Vec3::new((i % 4) as f32, (i / 4 % 4) as f32, (i / 16) as f32);
        c.push_activated(p, Vec3::splat(0.1), Quat::IDENTITY, 0.5, Vec3::ONE);
    }
    c
}

fn own() -> Vec<Camera> {
    vec![Camera::look_at(
        DVec3::new(0.0, 0.0, -5.0),
        DVec3::ZERO,
        DVec3::NEG_Y,
        60.0,
        200,
        100,
    )
    .unwrap()]
}

#[test]
fn one_orbit_camera_is_the_rigs_camera_bit_for_bit() {
    let c = cloud();
    let rig = OrbitRig::default();
    let all = rig.cameras(&c, 7).unwrap();
    for (i, cam) in all.iter().enumerate() {
        assert_eq!(&rig.camera(&c, 7, i).unwrap(), cam);
        let req = CameraRequest::new(CameraSpec::Orbit { n: 7, index: i });
        let own = own();
        let got = req
            .resolve(CameraSource {
                cloud: &c,
                own: &own,
            })
            .unwrap();
        assert_eq!(&got, cam);
    }
}

#[test]
fn a_huge_orbit_builds_one_camera_and_an_oversized_one_is_refused() {
    let c = cloud();
    // At the cap, camera I alone is built (a whole rig of this size would be 100,000 cameras).
    let spec: CameraSpec = format!("orbit:{MAX_ORBIT_CAMERAS}:12345").parse().unwrap();
    let cam = CameraRequest::new(spec)
        .resolve(CameraSource {
            cloud: &c,
            own: &[],
        })
        .unwrap();
    assert_eq!(cam.name, format!("orbit 12345/{MAX_ORBIT_CAMERAS}"));
    let e = "orbit:1000000000:5".parse::<CameraSpec>().unwrap_err();
    assert!(e.to_string().contains("N must be in"), "{e}");
    assert!(parse_camera_list("orbit:1000000000").is_err());
    assert!("orbit:0:0".parse::<CameraSpec>().is_err());
}

#[test]
fn sizes_are_bounded_and_errors_name_the_option() {
    let c = cloud();
    let own = own();
    let src = CameraSource {
        cloud: &c,
        own: &own,
    };
    let mut req = CameraRequest::new(CameraSpec::Orbit { n: 4, index: 0 });
    req.width = Some(MAX_IMAGE_SIDE + 1);
    let e = req.resolve(src).unwrap_err().to_string();
    assert!(e.contains("--width"), "{e}");
    req.width = Some(0);
    assert!(req
        .resolve(src)
        .unwrap_err()
        .to_string()
        .contains("--width"));
    // Within the side limit but above the default budget: refused until the budget is raised.
    req.width = Some(MAX_IMAGE_SIDE);
    req.height = Some(MAX_IMAGE_SIDE / 2);
    let e = req.resolve(src).unwrap_err().to_string();
    assert!(e.contains("--max-pixels"), "{e}");
    assert!(u64::from(MAX_IMAGE_SIDE) * u64::from(MAX_IMAGE_SIDE / 2) > DEFAULT_PIXEL_BUDGET);
    req.max_pixels = u64::from(MAX_IMAGE_SIDE) * u64::from(MAX_IMAGE_SIDE / 2);
    let cam = req.resolve(src).unwrap();
    assert_eq!(
        (cam.width, cam.height),
        (MAX_IMAGE_SIDE, MAX_IMAGE_SIDE / 2)
    );
    // The scene's own camera, resized by one side, keeps its aspect.
    let mut req = CameraRequest::new(CameraSpec::Scene(0));
    req.width = Some(100);
    let cam = req.resolve(src).unwrap();
    assert_eq!((cam.width, cam.height), (100, 50));
    assert!(CameraRequest::new(CameraSpec::Scene(1))
        .resolve(src)
        .is_err());
}

#[test]
fn an_oversized_cameras_json_is_refused_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cameras.json");
    let mut cams = own();
    cams[0] = cams[0].resized(MAX_IMAGE_SIDE + 1, 10);
    save_cameras_json(&path, &cams).unwrap();
    let c = cloud();
    let spec: CameraSpec = format!("{}:0", path.display()).parse().unwrap();
    let e = CameraRequest::new(spec)
        .resolve(CameraSource {
            cloud: &c,
            own: &[],
        })
        .unwrap_err()
        .to_string();
    assert!(e.contains("cameras.json") && e.contains("width"), "{e}");
}

#[test]
fn camera_lists_expand_in_order() {
    let items = parse_camera_list("orbit:3, scene ,orbit:8:1").unwrap();
    assert_eq!(
        items,
        vec![
            CameraListItem::Orbit(3),
            CameraListItem::Scene,
            CameraListItem::One(CameraSpec::Orbit { n: 8, index: 1 }),
        ]
    );
    let c = cloud();
    let own = own();
    let mut req = CameraRequest::new(CameraSpec::Scene(0));
    req.width = Some(64);
    req.height = Some(48);
    let cams = req
        .resolve_list(
            &items,
            CameraSource {
                cloud: &c,
                own: &own,
            },
        )
        .unwrap();
    assert_eq!(cams.len(), 5);
    // Each expanded camera is what its single spec resolves to.
    for (i, cam) in cams[..3].iter().enumerate() {
        let one = req
            .with_spec(CameraSpec::Orbit { n: 3, index: i })
            .resolve(CameraSource {
                cloud: &c,
                own: &own,
            })
            .unwrap();
        assert_eq!(&one, cam);
    }
    assert_eq!((cams[3].width, cams[3].height), (64, 48));
    assert!(parse_camera_list(" , ").is_err());
    assert!(parse_camera_list("orbit:x").is_err());
}

#[test]
fn a_bare_cameras_file_in_a_list_means_all_of_its_cameras() {
    let items = parse_camera_list("orbit:2,views/cameras.json,a.json:1").unwrap();
    assert_eq!(
        items,
        vec![
            CameraListItem::Orbit(2),
            CameraListItem::File("views/cameras.json".into()),
            CameraListItem::One(CameraSpec::Json {
                path: "a.json".into(),
                index: 1
            }),
        ]
    );
}
