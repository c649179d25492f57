//! Screen-space subsurface scattering: skin, wax, marble and leaves soften as light
//! travels under their surface — put [`SubsurfaceScattering`] on a
//! [`PenumbraLighting`] camera and give a material a [`SubsurfaceProfile`] (a scatter
//! colour and a world-space radius).
//!
//! # Marking a material
//!
//! A profile is registered in [`SubsurfaceProfiles`], which names it by a deferred
//! lighting pass id; the material carries that id, and Bevy's G-buffer carries it per
//! pixel (its 8-bit lighting id, the only free field: Bevy's four G-buffer words are
//! packed full), as Unreal's G-buffer carries a subsurface profile id:
//!
//! ```no_run
//! # use bevy::prelude::*;
//! # use bevy_penumbra_cinematic::sss::{SubsurfaceProfile, SubsurfaceProfiles};
//! fn setup(mut profiles: ResMut<SubsurfaceProfiles>, mut materials: ResMut<Assets<StandardMaterial>>) {
//!     let skin = profiles
//!         .add(SubsurfaceProfile { scatter_color: Color::srgb(0.9, 0.45, 0.3), radius: 0.01 })
//!         .expect("fewer than 64 profiles");
//!     let material = materials.add(skin.apply(StandardMaterial::default()));
//! }
//! ```
//!
//! An `ExtendedMaterial<StandardMaterial, _>` carries the id in its base
//! (`SubsurfaceProfileId::apply` on the base); add [`ScatteringMaterialPlugin`] for it,
//! which finds its meshes as the plugin finds `StandardMaterial` ones (without it they
//! are found by no pass and stay unlit on Penumbra cameras).
//!
//! Lighting ids `192..=255` are profiles 0 to 63. Cameras without the component shade
//! such materials as ordinary `StandardMaterial`s: forward cameras and Penumbra cameras
//! without [`SubsurfaceScattering`] alike (a draw of Penumbra's lighting pass for those
//! ids; on `DeferredMsaa` cameras its multisampled pass shades them). Bevy's own deferred lighting pass lights one id per camera, so a plain deferred
//! camera (no `PenumbraLighting`) leaves them unlit, as it does every custom id.
//!
//! # The technique
//!
//! Samaritan's screen-space subsurface scattering (Mittring and Dudash, GDC 2011) with
//! Burley's normalized diffusion profile (Christensen and Burley 2015, the profile Unreal
//! and Unity HDRP use), in two draws on the scattering pixels only (depth-tested against
//! Bevy's lighting-id texture, in `Core3d`'s main pass after Penumbra's lighting):
//!
//! 1. **Split lighting**: Penumbra's light loop, run with the diffuse colour set to 0 and
//!    to 1 — every term is affine in it — writes what does not scale with the albedo
//!    (specular, emissive, the ambient's Fresnel part) and the diffuse irradiance (direct
//!    and indirect, with the distance-field shadows and AO) to two `Rgba16Float` targets.
//! 2. **Scatter**: each pixel gathers the irradiance of `samples` points on a disc in its
//!    tangent plane, at radii drawn from the widest channel's profile (so equal weights
//!    follow the profile), the disc rotated and jittered per pixel (and per frame with
//!    `temporal`), projected to the screen. A sample counts where the pixel there has
//!    the same profile, weighted per channel by the profile at the world-space distance
//!    between the two surface points (never under the disc's radius) over the density it
//!    was drawn with, and the sum is normalised per channel: a sample across a silhouette
//!    or a depth step lands far away in world space and weighs next to nothing; a
//!    non-scattering pixel is never sampled. The pixel's diffuse colour multiplies the
//!    result (the albedo is applied after the blur, not blurred), the first target is
//!    added, then Bevy's fog and in-shader tonemapping.
//!
//! Specular light is never scattered; non-scattering pixels are not touched (bit for
//! bit). The CPU model is `penumbra_reference::sss::scatter_screen`, checked against a
//! world-space convolution of the irradiance over the surface.
//!
//! # Limits
//!
//! - Screen space: light from surfaces outside the view or hidden behind others does not
//!   scatter in, and thin parts do not transmit light from behind (no transmission).
//! - The normalisation is per pixel over the samples kept: near a silhouette the profile
//!   is renormalised over the visible surface, as Jimenez's and Unreal's are.
//! - Noise: each pixel's disc is rotated and jittered by a hash, so a single frame shows
//!   speckle where the profile's long tail reaches from light into shade (at 16 samples,
//!   mean error 0.0244 of the lit level across a shadow edge against a world-space
//!   convolution; 0.0094 averaged over 8 frames). With `temporal`, a temporal
//!   anti-aliasing filter averages it.
//! - On [`DeferredMsaa`](bevy_penumbra_df::DeferredMsaa) cameras both draws run once
//!   per pixel, after the lighting pass: split lighting from the pixel's first sample
//!   holding a scattering material (its lighting id marks the irradiance, since the
//!   ids are multisampled there), then the scatter, written through the sample mask to
//!   the scattering samples only, replacing the multisampled lighting pass's ordinary
//!   shading of them (`MsaaShadedLightingIds`: the light loop runs three times on those
//!   pixels). A pixel's scattering samples share one colour: the edge between two
//!   scattering materials is not antialiased; the edge against anything else is.
//!
//! Cost: nothing without the component or with no scattering material in the view. Per
//! camera with both: two `Rgba16Float` view-sized textures (16 bytes per pixel, 33 MB at
//! 1080p); the light loop twice on scattering pixels, and `samples` texture reads of
//! depth, lighting id and irradiance per scattering pixel. On lavapipe at 384 × 288 with
//! the material over 70 % of the view, frames take 58–60 ms at 16 samples (4: 44, 64:
//! 111–115) against 25–28 ms without scattering. Diagnostics: the time span
//! `penumbra_subsurface_scattering`.

mod render;

use bevy::prelude::*;
use bevy::render::{ExtractSchedule, RenderApp};
use bevy_penumbra_df::PenumbraLighting;
use bevy_penumbra_df::system_times::timed;
use penumbra_cinematic_core::sss::{FIRST_LIGHTING_ID, MAX_PROFILES, ScatterProfile};

/// Adds [`SubsurfaceScattering`] and the [`SubsurfaceProfiles`] resource. Part of
/// `PenumbraPlugins` (feature `sss`); needs `PenumbraLightingPlugin`.
#[derive(Default)]
pub struct SubsurfaceScatteringPlugin;

/// Subsurface scattering on a [`PenumbraLighting`] camera (the [module docs](self)).
#[derive(Component, Reflect, Clone, Debug, PartialEq)]
#[reflect(Component, Clone, Default)]
#[require(PenumbraLighting)]
pub struct SubsurfaceScattering {
    /// Disc samples per scattering pixel, `1..=64`. Default 16 (Samaritan's). Cost:
    /// linear (three texture reads each).
    pub samples: u32,
    /// Rotate and jitter the disc per frame as well as per pixel, for a temporal
    /// anti-aliasing filter to average; without one the noise then shimmers. Default
    /// false. No cost.
    pub temporal: bool,
    /// Shows a pass's intermediate values. Default [`SubsurfaceDebugView::None`].
    pub debug_view: SubsurfaceDebugView,
}

impl Default for SubsurfaceScattering {
    fn default() -> Self {
        SubsurfaceScattering {
            samples: 16,
            temporal: false,
            debug_view: SubsurfaceDebugView::None,
        }
    }
}

impl SubsurfaceScattering {
    /// The most samples per pixel.
    pub const MAX_SAMPLES: u32 = 64;

    /// Samples per pixel, clamped to `1..=64`, and what was out of range.
    pub fn resolve(&self) -> (u32, Option<String>) {
        let samples = self.samples.clamp(1, Self::MAX_SAMPLES);
        let problem = (samples != self.samples)
            .then(|| format!("samples {} outside 1..=64 (using {samples})", self.samples));
        (samples, problem)
    }
}

/// What a [`SubsurfaceScattering`] camera shows on scattering pixels.
#[derive(Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SubsurfaceDebugView {
    /// The shaded image.
    #[default]
    None,
    /// The diffuse irradiance before scattering (linear, exposed, alpha `2 + profile`).
    Irradiance,
    /// The diffuse irradiance after scattering (linear, exposed, alpha `2 + profile`).
    Scattered,
}

/// A scattering material's look: how far light travels under its surface, per colour.
#[derive(Reflect, Clone, Copy, Debug, PartialEq)]
#[reflect(Clone, Default)]
pub struct SubsurfaceProfile {
    /// How far each colour channel spreads, as a fraction of `radius` (linear channels in
    /// `[0, 1]`; skin scatters red furthest). Default `srgb(0.9, 0.45, 0.3)`.
    pub scatter_color: Color,
    /// World-space scatter distance of a channel at 1: Burley's shape distance `d`
    /// (the profile keeps 90 % of its energy within about `4.6 d`), metres. Default
    /// 0.005 (5 mm, skin). Cost: none per se, but a wider disc in pixels reads texels
    /// further apart.
    pub radius: f32,
}

impl Default for SubsurfaceProfile {
    fn default() -> Self {
        SubsurfaceProfile {
            scatter_color: Color::srgb(0.9, 0.45, 0.3),
            radius: 0.005,
        }
    }
}

impl SubsurfaceProfile {
    /// The profile the pass uses: the colour's linear channels clamped to `[0, 1]` (NaN
    /// to 0), the radius to `≥ 0` (NaN to 0: no scattering), and what was out of range.
    pub fn resolve(&self) -> (ScatterProfile, Vec<String>) {
        let mut problems = Vec::new();
        let linear = LinearRgba::from(self.scatter_color);
        let colour = Vec3::new(linear.red, linear.green, linear.blue);
        let clean = Vec3::from_array(colour.to_array().map(|c| if c.is_nan() { 0.0 } else { c }))
            .clamp(Vec3::ZERO, Vec3::ONE);
        if clean != colour {
            problems.push(format!(
                "scatter colour {colour} outside [0, 1] (using {clean})"
            ));
        }
        let radius = if self.radius > 0.0 && self.radius.is_finite() {
            self.radius
        } else {
            problems.push(format!(
                "radius {} is not a positive number of metres (no scattering)",
                self.radius
            ));
            0.0
        };
        (ScatterProfile::new(clean, radius), problems)
    }
}

/// A profile's name: the deferred lighting pass id its materials carry.
#[derive(Reflect, Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct SubsurfaceProfileId(u8);

impl SubsurfaceProfileId {
    /// The profile's index in [`SubsurfaceProfiles`].
    pub fn index(self) -> usize {
        usize::from(self.0 - FIRST_LIGHTING_ID)
    }

    /// The `deferred_lighting_pass_id` of materials with this profile.
    pub fn lighting_pass_id(self) -> u8 {
        self.0
    }

    /// The profile of a material's lighting pass id, if it names one.
    pub fn of_lighting_pass_id(id: u8) -> Option<Self> {
        (id >= FIRST_LIGHTING_ID).then_some(SubsurfaceProfileId(id))
    }

    /// `material` with this profile (its `deferred_lighting_pass_id` set).
    pub fn apply(self, material: StandardMaterial) -> StandardMaterial {
        StandardMaterial {
            deferred_lighting_pass_id: self.0,
            ..material
        }
    }
}

/// The app's scattering profiles, at most 64 (the lighting ids `192..=255`).
#[derive(Resource, Reflect, Clone, Debug, Default, PartialEq)]
#[reflect(Resource, Clone, Default)]
pub struct SubsurfaceProfiles {
    profiles: Vec<SubsurfaceProfile>,
}

/// [`SubsurfaceProfiles::add`] when all 64 ids are taken.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SubsurfaceProfilesFull;

impl std::fmt::Display for SubsurfaceProfilesFull {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "all {MAX_PROFILES} subsurface profiles are in use")
    }
}

impl std::error::Error for SubsurfaceProfilesFull {}

impl SubsurfaceProfiles {
    /// Registers a profile and names it.
    pub fn add(
        &mut self,
        profile: SubsurfaceProfile,
    ) -> Result<SubsurfaceProfileId, SubsurfaceProfilesFull> {
        if self.profiles.len() >= MAX_PROFILES {
            return Err(SubsurfaceProfilesFull);
        }
        self.profiles.push(profile);
        Ok(SubsurfaceProfileId(
            FIRST_LIGHTING_ID + (self.profiles.len() - 1) as u8,
        ))
    }

    /// A registered profile.
    pub fn get(&self, id: SubsurfaceProfileId) -> Option<&SubsurfaceProfile> {
        self.profiles.get(id.index())
    }

    /// A registered profile, to edit (materials with it follow the next frame).
    pub fn get_mut(&mut self, id: SubsurfaceProfileId) -> Option<&mut SubsurfaceProfile> {
        self.profiles.get_mut(id.index())
    }

    /// The registered profiles, in id order.
    pub fn iter(&self) -> impl Iterator<Item = (SubsurfaceProfileId, &SubsurfaceProfile)> {
        self.profiles
            .iter()
            .enumerate()
            .map(|(k, p)| (SubsurfaceProfileId(FIRST_LIGHTING_ID + k as u8), p))
    }

    /// Whether no profile is registered.
    pub fn is_empty(&self) -> bool {
        self.profiles.is_empty()
    }
}

/// Warns once per change when a profile or a camera's settings are out of range.
fn warn_bad_subsurface_settings(
    profiles: Res<SubsurfaceProfiles>,
    cameras: Query<(Entity, &SubsurfaceScattering), Changed<SubsurfaceScattering>>,
) {
    if profiles.is_changed() {
        for (id, profile) in profiles.iter() {
            let (_, problems) = profile.resolve();
            if !problems.is_empty() {
                warn!(
                    "Penumbra: subsurface profile {} (lighting id {}): {}; clamped",
                    id.index(),
                    id.lighting_pass_id(),
                    problems.join(", ")
                );
            }
        }
    }
    for (entity, settings) in &cameras {
        if let (_, Some(problem)) = settings.resolve() {
            warn!("Penumbra: SubsurfaceScattering on {entity}: {problem}; clamped");
        }
    }
}

/// A material whose meshes can carry a subsurface profile: it says which deferred
/// lighting pass id it writes to the G-buffer. `StandardMaterial` and
/// `ExtendedMaterial<StandardMaterial, _>` (the base's id) are; register one with
/// [`ScatteringMaterialPlugin`].
pub trait ScatteringMaterial: Material {
    /// The deferred lighting pass id the material writes (`deferred_lighting_pass_id`).
    fn lighting_pass_id(&self) -> u8;
}

impl ScatteringMaterial for StandardMaterial {
    fn lighting_pass_id(&self) -> u8 {
        self.deferred_lighting_pass_id
    }
}

impl<E: bevy::pbr::MaterialExtension> ScatteringMaterial
    for bevy::pbr::ExtendedMaterial<StandardMaterial, E>
{
    fn lighting_pass_id(&self) -> u8 {
        self.base.deferred_lighting_pass_id
    }
}

/// Lets the meshes of material `M` whose lighting id names a profile be shaded: scattered
/// on [`SubsurfaceScattering`] cameras, lit as ordinary `StandardMaterial`s on other
/// Penumbra cameras. [`SubsurfaceScatteringPlugin`] adds it for `StandardMaterial`; add it
/// for an `ExtendedMaterial<StandardMaterial, _>` whose base carries a profile id
/// (`SubsurfaceProfileId::apply`), after the material's own `MaterialPlugin`. Without
/// it such meshes are found by no pass and stay unlit. Cost: as for `StandardMaterial`
/// meshes (an index of the meshes by material while a profile and a Penumbra camera
/// exist).
pub struct ScatteringMaterialPlugin<M>(std::marker::PhantomData<fn() -> M>);

impl<M> Default for ScatteringMaterialPlugin<M> {
    fn default() -> Self {
        Self(std::marker::PhantomData)
    }
}

impl<M: ScatteringMaterial> Plugin for ScatteringMaterialPlugin<M> {
    fn build(&self, app: &mut App) {
        app.init_resource::<render::ScatteringMeshes<M>>()
            .add_systems(
                PostUpdate,
                // After the frame's material edits become events.
                timed(render::find_scattering_meshes::<M>).after(bevy::asset::AssetEventSystems),
            );
        if let Some(render_app) = app.get_sub_app_mut(RenderApp) {
            render_app.add_systems(
                ExtractSchedule,
                timed(render::extract_scattering_meshes::<M>),
            );
        }
    }
}

impl Plugin for SubsurfaceScatteringPlugin {
    fn build(&self, app: &mut App) {
        bevy_penumbra_df::register_shader_library(app);
        app.register_type::<SubsurfaceScattering>()
            .register_type::<SubsurfaceProfiles>()
            .init_resource::<SubsurfaceProfiles>()
            .add_plugins((
                render::sync_plugin(),
                ScatteringMaterialPlugin::<StandardMaterial>::default(),
            ))
            .add_systems(PostUpdate, timed(warn_bad_subsurface_settings));
        if let Some(render_app) = app.get_sub_app_mut(RenderApp) {
            render::build(render_app);
        }
    }

    fn finish(&self, app: &mut App) {
        if let Some(render_app) = app.get_sub_app_mut(RenderApp) {
            render::finish(render_app);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn profiles_name_lighting_ids_and_fill_up() {
        let mut profiles = SubsurfaceProfiles::default();
        let first = profiles.add(SubsurfaceProfile::default()).unwrap();
        assert_eq!(first.lighting_pass_id(), 192);
        assert_eq!(first.index(), 0);
        assert_eq!(SubsurfaceProfileId::of_lighting_pass_id(192), Some(first));
        assert_eq!(SubsurfaceProfileId::of_lighting_pass_id(1), None);
        for _ in 1..MAX_PROFILES {
            profiles.add(SubsurfaceProfile::default()).unwrap();
        }
        assert_eq!(
            profiles.iter().last().unwrap().0.lighting_pass_id(),
            255,
            "the last id"
        );
        assert_eq!(
            profiles.add(SubsurfaceProfile::default()),
            Err(SubsurfaceProfilesFull)
        );
        let material = first.apply(StandardMaterial::default());
        assert_eq!(material.deferred_lighting_pass_id, 192);
    }

    /// The main world's list of scattering meshes follows material handles, despawns
    /// and material edits, and is empty while no Penumbra camera exists.
    #[test]
    fn scattering_meshes_follow_materials() {
        let mut app = App::new();
        app.add_plugins((MinimalPlugins, AssetPlugin::default()))
            .init_asset::<StandardMaterial>()
            .init_resource::<SubsurfaceProfiles>()
            .init_resource::<render::ScatteringMeshes>()
            .add_systems(
                PostUpdate,
                render::find_scattering_meshes::<StandardMaterial>
                    .after(bevy::asset::AssetEventSystems),
            );
        let world = app.world_mut();
        let skin = world
            .resource_mut::<SubsurfaceProfiles>()
            .add(SubsurfaceProfile::default())
            .unwrap();
        let mut assets = world.resource_mut::<Assets<StandardMaterial>>();
        let plain = assets.add(StandardMaterial::default());
        let scattering = assets.add(skin.apply(StandardMaterial::default()));
        let a = world.spawn(MeshMaterial3d(plain)).id();
        let b = world.spawn(MeshMaterial3d(scattering.clone())).id();
        let meshes = |app: &mut App| {
            app.update();
            app.world().resource::<render::ScatteringMeshes>().sorted()
        };
        assert_eq!(meshes(&mut app), [], "no Penumbra camera");
        app.world_mut().spawn(PenumbraLighting);
        assert_eq!(meshes(&mut app), [b]);
        app.world_mut()
            .entity_mut(a)
            .insert(MeshMaterial3d(scattering.clone()));
        let mut both = vec![a, b];
        both.sort();
        assert_eq!(meshes(&mut app), both, "a material handle changed");
        app.world_mut().entity_mut(b).despawn();
        assert_eq!(meshes(&mut app), [a], "despawned");
        app.world_mut()
            .resource_mut::<Assets<StandardMaterial>>()
            .get_mut(&scattering)
            .unwrap()
            .deferred_lighting_pass_id = 1;
        assert_eq!(meshes(&mut app), [], "the material lost its profile");
    }

    /// A material edit re-examines the meshes with that material, not every mesh: of
    /// 1,000 meshes with their own materials, editing one examines one.
    #[test]
    fn a_material_edit_examines_only_its_meshes() {
        const MESHES: usize = 1_000;
        let mut app = App::new();
        app.add_plugins((MinimalPlugins, AssetPlugin::default()))
            .init_asset::<StandardMaterial>()
            .init_resource::<SubsurfaceProfiles>()
            .init_resource::<render::ScatteringMeshes>()
            .add_systems(
                PostUpdate,
                render::find_scattering_meshes::<StandardMaterial>
                    .after(bevy::asset::AssetEventSystems),
            );
        let world = app.world_mut();
        let skin = world
            .resource_mut::<SubsurfaceProfiles>()
            .add(SubsurfaceProfile::default())
            .unwrap();
        world.spawn(PenumbraLighting);
        let materials: Vec<Handle<StandardMaterial>> = (0..MESHES)
            .map(|k| {
                let material = if k % 2 == 0 {
                    skin.apply(StandardMaterial::default())
                } else {
                    StandardMaterial::default()
                };
                world
                    .resource_mut::<Assets<StandardMaterial>>()
                    .add(material)
            })
            .collect();
        let entities: Vec<Entity> = materials
            .iter()
            .map(|m| world.spawn(MeshMaterial3d(m.clone())).id())
            .collect();
        let run = |app: &mut App| {
            app.update();
            let found = app.world().resource::<render::ScatteringMeshes>();
            (found.sorted().len(), found.examined())
        };
        assert_eq!(run(&mut app), (MESHES / 2, MESHES), "the first scan");
        assert_eq!(run(&mut app), (MESHES / 2, 0), "nothing changed");
        // One material loses its profile, another gains one.
        for (k, id) in [(0, 1), (1, FIRST_LIGHTING_ID)] {
            app.world_mut()
                .resource_mut::<Assets<StandardMaterial>>()
                .get_mut(&materials[k])
                .unwrap()
                .deferred_lighting_pass_id = id;
        }
        let (found, examined) = run(&mut app);
        println!("{MESHES} meshes, 2 materials edited: {examined} meshes examined");
        assert_eq!(found, MESHES / 2);
        assert_eq!(examined, 2, "meshes examined for 2 edited materials");
        let found = app.world().resource::<render::ScatteringMeshes>().sorted();
        assert!(!found.contains(&entities[0]) && found.contains(&entities[1]));
        // A mesh sharing an edited material is examined with it; a new handle on a mesh
        // is examined alone.
        app.world_mut()
            .entity_mut(entities[3])
            .insert(MeshMaterial3d(materials[1].clone()));
        assert_eq!(run(&mut app), (MESHES / 2 + 1, 1), "a handle changed");
        app.world_mut()
            .resource_mut::<Assets<StandardMaterial>>()
            .get_mut(&materials[1])
            .unwrap()
            .deferred_lighting_pass_id = 1;
        assert_eq!(
            run(&mut app),
            (MESHES / 2 - 1, 2),
            "a shared material edited"
        );
    }

    #[test]
    fn bad_profiles_are_clamped_and_named() {
        let (good, problems) = SubsurfaceProfile::default().resolve();
        assert!(problems.is_empty());
        assert!(good.d.max_element() > 0.0);
        for radius in [0.0, -1.0, f32::NAN, f32::INFINITY] {
            let (p, problems) = SubsurfaceProfile {
                radius,
                ..default()
            }
            .resolve();
            assert_eq!(p.d, Vec3::ZERO, "radius {radius}");
            assert_eq!(problems.len(), 1, "radius {radius}");
        }
        let (p, problems) = SubsurfaceProfile {
            scatter_color: Color::linear_rgb(2.0, -1.0, f32::NAN),
            radius: 0.01,
        }
        .resolve();
        assert_eq!(p.d, Vec3::new(0.01, 0.0, 0.0));
        assert!(problems[0].contains("outside [0, 1]"), "{problems:?}");
        let (samples, problem) = SubsurfaceScattering {
            samples: 0,
            ..default()
        }
        .resolve();
        assert_eq!(samples, 1);
        assert!(problem.is_some());
        assert_eq!(SubsurfaceScattering::default().resolve(), (16, None));
    }
}
