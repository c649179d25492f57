//! `penumbra-bake`: bake a mesh into a signed distance field.
//!
//! ```text
//! penumbra-bake MESH [--resolution N | --voxels-per-unit V] [--sign METHOD] [--two-sided]
//!               [--out FILE] [--npy FILE]
//! ```

use penumbra_sdf::{
    BakeSettings, GridPolicy, Resolution, SignMethod, bake, format, load_mesh_file,
};
use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

const USAGE: &str = "\
usage: penumbra-bake MESH [--resolution N | --voxels-per-unit V] [--sign METHOD]
                     [--two-sided] [--out FILE] [--npy FILE] [--mesh NAME]

  MESH                 a Wavefront .obj, or a .gltf / .glb scene (all meshes of the
                       default scene, placed by their node transforms)
  --mesh NAME          glTF only: bake the mesh NAME alone, in its own space
  --resolution N       N samples along the longest axis (including a 2-sample border)
  --voxels-per-unit V  V samples per mesh unit, each axis clamped to 8..=256
                       (default: 32 per unit, like Unreal's defaults, and at
                       least 48 samples along the longest axis)
  --sign METHOD        winding (default) | backface | parity | two-sided |
                       ground (an open sheet facing +y, solid below: terrain, floors)
  --two-sided          same as --sign two-sided (foliage: a thin shell around surfaces)
  --out FILE           write the field as .psdf (default: MESH with extension .psdf)
  --npy FILE           also write float32 (nz, ny, nx) .npy plus FILE.json (origin,
                       voxel_size, dims); a[k, j, i] is the distance at
                       origin + voxel_size * (i, j, k); negative inside";

struct Args {
    mesh: PathBuf,
    resolution: Option<Resolution>,
    sign: SignMethod,
    out: Option<PathBuf>,
    npy: Option<PathBuf>,
    mesh_name: Option<String>,
}

fn parse(args: impl IntoIterator<Item = String>) -> Result<Args, String> {
    let mut mesh = None;
    let mut out = Args {
        mesh: PathBuf::new(),
        resolution: None,
        sign: SignMethod::WindingNumber,
        out: None,
        npy: None,
        mesh_name: None,
    };
    let mut args = args.into_iter();
    while let Some(a) = args.next() {
        let mut value = |flag: &str| args.next().ok_or(format!("{flag} needs a value"));
        match a.as_str() {
            "-h" | "--help" => return Err(USAGE.into()),
            "--resolution" => {
                let v = value("--resolution")?;
                let n: u32 = v
                    .parse()
                    .map_err(|_| format!("--resolution: bad number {v:?}"))?;
                if out.resolution.is_some() {
                    return Err("give only one of --resolution and --voxels-per-unit".into());
                }
                out.resolution = Some(Resolution::LongestAxis(n));
            }
            "--voxels-per-unit" => {
                let v = value("--voxels-per-unit")?;
                let d: f32 = v
                    .parse()
                    .map_err(|_| format!("--voxels-per-unit: bad number {v:?}"))?;
                if out.resolution.is_some() {
                    return Err("give only one of --resolution and --voxels-per-unit".into());
                }
                out.resolution = Some(Resolution::PerUnit {
                    density: d,
                    min: 8,
                    max: 256,
                    min_longest: 0,
                });
            }
            "--sign" => {
                out.sign = match value("--sign")?.as_str() {
                    "winding" => SignMethod::WindingNumber,
                    "backface" => SignMethod::BACKFACE_RATIO,
                    "parity" => SignMethod::RayParity,
                    "two-sided" => SignMethod::TWO_SIDED,
                    "ground" => SignMethod::SolidBelow { up: glam::Vec3::Y },
                    other => {
                        return Err(format!(
                            "--sign: unknown method {other:?} (winding, backface, parity, two-sided, ground)"
                        ));
                    }
                }
            }
            "--two-sided" => out.sign = SignMethod::TWO_SIDED,
            "--out" => out.out = Some(value("--out")?.into()),
            "--npy" => out.npy = Some(value("--npy")?.into()),
            "--mesh" => out.mesh_name = Some(value("--mesh")?),
            flag if flag.starts_with("--") => {
                return Err(format!("unknown option {flag}\n{USAGE}"));
            }
            path => {
                if mesh.replace(PathBuf::from(path)).is_some() {
                    return Err(format!("more than one MESH given\n{USAGE}"));
                }
            }
        }
    }
    out.mesh = mesh.ok_or(USAGE)?;
    Ok(out)
}

fn write(path: &Path, bytes: &[u8]) -> Result<(), String> {
    std::fs::write(path, bytes).map_err(|e| format!("writing {}: {e}", path.display()))
}

fn run(args: Args) -> Result<(), String> {
    let start = Instant::now();
    let (mesh, notes) = load_mesh_file(&args.mesh, args.mesh_name.as_deref())
        .map_err(|e| format!("{}: {e}", args.mesh.display()))?;
    for note in notes {
        eprintln!("penumbra-bake: note: {note}");
    }
    let settings = BakeSettings {
        grid: GridPolicy {
            resolution: args.resolution.unwrap_or(GridPolicy::default().resolution),
            // An explicit resolution is the grid asked for; the default one refines
            // thin-walled meshes as runtime bakes do.
            thin_walls: if args.resolution.is_some() {
                penumbra_sdf::grid::ThinWalls::OFF
            } else {
                penumbra_sdf::grid::ThinWalls::default()
            },
            ..Default::default()
        },
        sign: args.sign,
        ..Default::default()
    };
    let show_progress = std::io::stderr().is_terminal();
    let progress = |f: f32| {
        if show_progress && start.elapsed().as_secs_f32() > 0.3 {
            let filled = (f * 30.0) as usize;
            eprint!(
                "\r[{}{}] {:3.0}%",
                "#".repeat(filled),
                " ".repeat(30 - filled),
                f * 100.0
            );
        }
    };
    let baked = bake(&mesh, &settings, Some(&progress))
        .map_err(|e| format!("{}: {e}", args.mesh.display()))?;
    if show_progress && start.elapsed().as_secs_f32() > 0.3 {
        eprintln!();
    }
    let v = &baked.volume;
    if std::env::var_os("PENUMBRA_BAKE_TIMINGS").is_some() {
        eprintln!("penumbra-bake: timings {:?}", baked.timings);
    }
    let out = args.out.unwrap_or_else(|| args.mesh.with_extension("psdf"));
    write(&out, &format::to_bytes(v))?;
    if let Some(npy) = &args.npy {
        write(npy, &format::to_npy(v))?;
        let mut json = npy.clone().into_os_string();
        json.push(".json");
        write(Path::new(&json), format::npy_sidecar_json(v).as_bytes())?;
    }
    let mut stdout = std::io::stdout().lock();
    writeln!(
        stdout,
        "{}: {} triangles ({} degenerate dropped), {}x{}x{} samples, voxel {:.6}, {:.3} s, {:.1}% inside -> {}",
        args.mesh.display(),
        baked.mesh.triangles,
        baked.mesh.degenerate_dropped,
        v.dims.x,
        v.dims.y,
        v.dims.z,
        v.voxel_size,
        start.elapsed().as_secs_f64(),
        v.inside_fraction() * 100.0,
        out.display()
    )
    .ok();
    Ok(())
}

fn main() -> ExitCode {
    let args = match parse(std::env::args().skip(1)) {
        Ok(a) => a,
        Err(e) => {
            eprintln!("{e}");
            return ExitCode::from(2);
        }
    };
    match run(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("penumbra-bake: {e}");
            ExitCode::FAILURE
        }
    }
}
