//! The viewer's command line (`clap`), validated before Bevy starts: every flag takes
//! `--flag value` or `--flag=value`; vectors are `X,Y,Z` and may start with a minus sign.

use bevy::math::{UVec2, Vec3};
use clap::Parser;
use std::path::PathBuf;

/// Any glTF 2.0 scene with Penumbra on: distance-field casters for its meshes, a sun and
/// its own punctual lights with distance-field shadows, an egui panel (windowed), or a
/// headless render with buffer dumps for checking against ray-traced truth.
#[derive(Parser, Clone, Debug, PartialEq)]
#[command(name = "viewer", about, long_about = None)]
pub struct Args {
    /// A `.glb` or `.gltf` file. None: Penumbra's showcase room.
    pub scene: Option<PathBuf>,
    /// Render into an image (no window). The default when no display is reachable.
    #[arg(long)]
    pub headless: bool,
    /// Image or window size, `WxH` pixels. Default 512x512 headless, 1280x720 windowed.
    #[arg(long, value_parser = parse_size, allow_hyphen_values = true)]
    pub size: Option<UVec2>,
    /// Frames rendered before the capture (headless; windowed: exit after N frames).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=100_000), allow_hyphen_values = true)]
    pub frames: Option<u32>,
    /// The PNG to write (headless default: viewer.png).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Camera position, metres (scene units). Default: framed on the scene's bounds.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub eye: Option<Vec3>,
    /// The point the camera looks at (+Y up). Default: the bounds' centre.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub target: Option<Vec3>,
    /// Vertical field of view, degrees, in (0, 180). Pinhole camera.
    #[arg(long, default_value_t = 45.0, value_parser = parse_fov, allow_hyphen_values = true)]
    pub fov: f32,
    /// The direction the sun's light travels (the `DirectionalLight`'s forward).
    /// Default -0.4,-1,-0.3.
    #[arg(long, value_parser = parse_direction, allow_hyphen_values = true)]
    pub sun: Option<Vec3>,
    /// The sun's angular diameter, degrees, in [0, 90). Default 0.533 (the sun's).
    #[arg(long, default_value_t = 0.533, value_parser = parse_angle, allow_hyphen_values = true)]
    pub angle: f32,
    /// A point light at X,Y,Z (repeatable).
    #[arg(long = "point", value_parser = parse_vec3, allow_hyphen_values = true)]
    pub points: Vec<Vec3>,
    /// The radius of the point light given in the same position (repeatable; default 0).
    #[arg(long = "radius", value_parser = parse_radius, allow_hyphen_values = true)]
    pub radii: Vec<f32>,
    /// Leave out the scene's own punctual lights (`KHR_lights_punctual`).
    #[arg(long)]
    pub no_scene_lights: bool,
    /// After the last frame, write the view's Penumbra buffers to DIR as `.npy` files and
    /// `meta.json` (headless only).
    #[arg(long)]
    pub dump: Option<PathBuf>,
    /// Distance-field ambient occlusion on the camera with this max occlusion distance,
    /// metres (scene units, not scaled), > 0; its other settings are the defaults.
    /// `--dump` then writes `ao` and `bent_normal`.
    #[arg(long, value_parser = parse_distance, allow_hyphen_values = true)]
    pub ao_max_distance: Option<f32>,
    /// Bevy's own `ScreenSpaceAmbientOcclusion` (its defaults) on the camera, to compare
    /// with DFAO on the same view. `--dump` then writes `ssao` (Bevy's SSAO visibility),
    /// unless `--ao-max-distance` is given too (its planes win).
    #[arg(long)]
    pub ssao: bool,
    /// Plain Bevy: no Penumbra on the camera or the lights (shadow maps), to compare.
    #[arg(long)]
    pub plain: bool,
    /// Scatter bokeh depth of field (`BokehDepthOfField`, hexagonal aperture) at this
    /// f-number, > 0, focused on the framed scene's centre; its other settings are the
    /// defaults.
    #[arg(long, value_parser = parse_f_stops, allow_hyphen_values = true)]
    pub bokeh: Option<f32>,
    /// When the scene's meshes bake two-sided (a shell about the surface):
    /// `never`, `material` (double-sided and open, or alpha-masked: the default) or
    /// `always` (`DistanceFieldSceneCasters::two_sided`).
    #[arg(long, value_parser = parse_two_sided, default_value = "material")]
    pub two_sided: penumbra::df::SceneTwoSided,
    /// Every mesh caster's distance-field resolution scale
    /// (`DistanceFieldCaster::resolution_scale`, Unreal's "distance field resolution
    /// scale"): 2 halves the voxels' size (8× the atlas), 0.5 doubles it. 1/16 to 8.
    #[arg(long, value_parser = parse_resolution_scale, default_value = "1")]
    pub resolution_scale: f32,
    /// Keep every distance field dense in the atlas, none as sparse bricks
    /// (`DistanceFieldSceneSettings::sparse_min_bytes` = `u64::MAX`).
    #[arg(long)]
    pub dense: bool,
    /// How skinned meshes cast (`DistanceFieldSceneCasters::skinned`): `capsules` fitted
    /// to their joints (the default), their `bind-pose` field, or `skip`.
    #[arg(long, value_parser = parse_skinned, default_value = "capsules")]
    pub skinned: penumbra::df::SkinnedCasters,
    /// Re-bake every skinned mesh's distance field on the GPU from its pose, a cube of
    /// R³ samples (`DistanceFieldRebake`, R a multiple of 8 in 16–128), instead of
    /// `--skinned`. Default: off.
    #[arg(long, value_name = "R")]
    pub rebake: Option<u32>,
    /// The fraction of each joint's vertices its fitted capsule holds, in (0, 1]
    /// (`SkinCapsuleFit::coverage`; only a mesh without usable triangles is fitted by
    /// its vertices, the rest by volume). Default: the fit's.
    #[arg(long, value_parser = parse_coverage, allow_hyphen_values = true)]
    pub capsule_coverage: Option<f32>,
    /// Pose the scene in its glTF animation N (0-based) at `--time`, held still (the
    /// nodes' transforms sampled by `penumbra_reference::posed_gltf`, the same pose the
    /// ray-traced truth uses). Default: the rest pose.
    #[arg(long, allow_hyphen_values = true)]
    pub animation: Option<usize>,
    /// A ground under the scene: a square at the bottom of its bounds, four bounds'
    /// radii across, casting as a `CasterSource::Plane` (for a character or a prop that
    /// stands on nothing in its file). `--dump`'s `meta.json` describes it; the truth
    /// adds its two triangles. Default: on for a scene with a skinned mesh (a character
    /// casts its shadow on it), off otherwise.
    #[arg(long, overrides_with = "no_ground")]
    pub ground: bool,
    /// No ground, even under a skinned mesh.
    #[arg(long, overrides_with = "ground")]
    pub no_ground: bool,
    /// Seconds into `--animation`, ≥ 0. Default 0.
    #[arg(long, value_parser = parse_time, allow_hyphen_values = true)]
    pub time: Option<f32>,
}

fn parse_skinned(s: &str) -> Result<penumbra::df::SkinnedCasters, String> {
    use penumbra::df::SkinnedCasters;
    match s {
        "skip" => Ok(SkinnedCasters::Skip),
        "bind-pose" => Ok(SkinnedCasters::BindPose),
        "capsules" => Ok(SkinnedCasters::Capsules),
        _ => Err(format!("{s}: not skip, bind-pose or capsules")),
    }
}

fn parse_coverage(s: &str) -> Result<f32, String> {
    match parse_number(s)? {
        c if c > 0.0 && c <= 1.0 => Ok(c),
        c => Err(format!("{c}: a coverage is in (0, 1]")),
    }
}

fn parse_time(s: &str) -> Result<f32, String> {
    match parse_number(s)? {
        t if t >= 0.0 => Ok(t),
        t => Err(format!("{t}: a time must be ≥ 0")),
    }
}

fn parse_resolution_scale(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if (1.0 / 16.0..=8.0).contains(&v) => Ok(v),
        _ => Err(format!("{s}: not a number from 0.0625 to 8")),
    }
}

fn parse_two_sided(s: &str) -> Result<penumbra::df::SceneTwoSided, String> {
    use penumbra::df::SceneTwoSided;
    match s {
        "never" => Ok(SceneTwoSided::Never),
        "material" => Ok(SceneTwoSided::FromMaterial),
        "always" => Ok(SceneTwoSided::Always),
        _ => Err(format!("{s}: not never, material or always")),
    }
}

impl Args {
    /// Parses and checks `args` (the program name first, as `std::env::args()`).
    pub fn parse_from_args<I, T>(args: I) -> Result<Args, clap::Error>
    where
        I: IntoIterator<Item = T>,
        T: Into<std::ffi::OsString> + Clone,
    {
        let args = Args::try_parse_from(args)?;
        args.check()?;
        Ok(args)
    }

    /// Checks across flags.
    fn check(&self) -> Result<(), clap::Error> {
        use clap::error::ErrorKind;
        let err = |msg: String| Err(clap::Error::raw(ErrorKind::ValueValidation, msg + "\n"));
        if self.radii.len() > self.points.len() {
            return err(format!(
                "--radius given {} times for {} --point",
                self.radii.len(),
                self.points.len()
            ));
        }
        if let (Some(eye), Some(target)) = (self.eye, self.target)
            && eye.distance(target) < 1e-6
        {
            return err("--eye and --target are the same point".into());
        }
        if let (Some(eye), Some(target)) = (self.eye, self.target) {
            let forward = (target - eye).normalize();
            if forward.cross(Vec3::Y).length() < 1e-6 {
                return err(
                    "--eye to --target is vertical: the camera's up (+Y) is undefined".into(),
                );
            }
        }
        if self.dump.is_some() && !self.headless {
            return err("--dump needs --headless".into());
        }
        if self.ao_max_distance.is_some() && self.plain {
            return err("--ao-max-distance is Penumbra's: not with --plain".into());
        }
        if self.time.is_some() && self.animation.is_none() {
            return err("--time needs --animation".into());
        }
        if self.animation.is_some() && self.scene.is_none() {
            return err("--animation poses a glTF scene: give one".into());
        }
        if self.dump.is_some() && self.plain {
            return err("--dump reads Penumbra's buffers: not with --plain".into());
        }
        Ok(())
    }

    /// The radius of point light `i`.
    pub fn radius(&self, i: usize) -> f32 {
        self.radii.get(i).copied().unwrap_or(0.0)
    }
}

fn finite(v: f32, what: &str) -> Result<f32, String> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(format!("{what} must be finite, got {v}"))
    }
}

fn parse_number(s: &str) -> Result<f32, String> {
    let v: f32 = s
        .trim()
        .parse()
        .map_err(|_| format!("not a number: {s:?}"))?;
    finite(v, "a number")
}

/// The largest coordinate `--eye`, `--target` and `--point` take, metres: far beyond any
/// scene, and small enough that the view's matrices stay finite (a finite 3·10³⁸ made a
/// NaN view).
pub const MAX_COORDINATE: f32 = 1.0e7;

/// `X,Y,Z`, each finite and within ±[`MAX_COORDINATE`].
pub fn parse_vec3(s: &str) -> Result<Vec3, String> {
    let parts: Vec<&str> = s.split(',').collect();
    if parts.len() != 3 {
        return Err(format!("expected X,Y,Z, got {s:?}"));
    }
    let v: Result<Vec<f32>, String> = parts.iter().map(|p| parse_number(p)).collect();
    let v = v?;
    if v.iter().any(|c| c.abs() > MAX_COORDINATE) {
        return Err(format!(
            "{s:?}: each coordinate must be within ±{MAX_COORDINATE:e}"
        ));
    }
    Ok(Vec3::new(v[0], v[1], v[2]))
}

/// A non-zero direction (not normalised here).
fn parse_direction(s: &str) -> Result<Vec3, String> {
    let v = parse_vec3(s)?;
    if v.length() < 1e-6 {
        return Err(format!("zero-length direction {s:?}"));
    }
    Ok(v)
}

/// `WxH`, each in 1..=8192.
fn parse_size(s: &str) -> Result<UVec2, String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or(format!("expected WxH, got {s:?}"))?;
    let dim = |d: &str| -> Result<u32, String> {
        let v: i64 = d
            .trim()
            .parse()
            .map_err(|_| format!("not a whole number: {d:?} in {s:?}"))?;
        if !(1..=8192).contains(&v) {
            return Err(format!("{v} is not in 1..=8192 (in {s:?})"));
        }
        Ok(v as u32)
    };
    Ok(UVec2::new(dim(w)?, dim(h)?))
}

fn parse_fov(s: &str) -> Result<f32, String> {
    let v = parse_number(s)?;
    if v <= 0.0 || v >= 180.0 {
        return Err(format!("must be in (0, 180) degrees, got {v}"));
    }
    Ok(v)
}

fn parse_angle(s: &str) -> Result<f32, String> {
    let v = parse_number(s)?;
    if !(0.0..90.0).contains(&v) {
        return Err(format!("must be in [0, 90) degrees, got {v}"));
    }
    Ok(v)
}

fn parse_distance(s: &str) -> Result<f32, String> {
    let v = parse_number(s)?;
    if v <= 0.0 {
        return Err(format!("must be > 0 metres, got {v}"));
    }
    Ok(v)
}

fn parse_f_stops(s: &str) -> Result<f32, String> {
    let v = parse_number(s)?;
    if v <= 0.0 {
        return Err(format!("must be a positive f-number, got {v}"));
    }
    Ok(v)
}

fn parse_radius(s: &str) -> Result<f32, String> {
    let v = parse_number(s)?;
    if v < 0.0 {
        return Err(format!("must be ≥ 0, got {v}"));
    }
    Ok(v)
}
