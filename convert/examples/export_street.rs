//! Export the `street` fixture (static Gaussians, two animated cars, four cameras) as a mesh
//! GLB, for the Blender and validator scripts: `export_street OUT.glb [PROFILE] [--surfels]`
//! (`--surfels`: split off opaque surfels with the default thresholds).

use splatbridge_convert::{convert_to_file, ConvertOptions, Profile};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let Some(out) = args.get(1) else {
        eprintln!(
            "usage: export_street OUT.glb|OUT.gltf|OUT.obj|OUT.ply [meshsplats|rings|texture] [--surfels]"
        );
        std::process::exit(2);
    };
    let profile = match args
        .get(2)
        .map(String::as_str)
        .filter(|a| !a.starts_with("--"))
    {
        None | Some("rings") => Profile::Rings,
        Some("meshsplats") => Profile::MeshSplats,
        Some("texture") => Profile::Texture,
        Some(p) => {
            eprintln!("error: unknown profile '{p}'");
            std::process::exit(2);
        }
    };
    let scene = splatbridge_scene::fixtures::street(1);
    // As `splatbridge convert` writes it (coplanar separation on: the file is for Blender).
    let opts = ConvertOptions {
        profile,
        coplanar_offset: true,
        surfels: args
            .iter()
            .any(|a| a == "--surfels")
            .then(splatbridge_convert::surfels::SurfelOptions::default),
        ..Default::default()
    };
    match convert_to_file(std::path::Path::new(out), &scene, None, &opts, false) {
        Ok(r) => println!("{}", serde_json::to_string(&r).unwrap_or_default()),
        Err(e) => {
            eprintln!("error: {e}");
            std::process::exit(2);
        }
    }
}
