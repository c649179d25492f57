//! An analytic ray-traced scene shaded exactly as Bevy shades `StandardMaterial`s: the
//! expected image of simple GPU render tests.
//!
//! One primary ray per pixel centre (the GPU test renders with MSAA off), hard shadows by
//! casting a ray toward each directional light (Bevy's shadow maps approximate exactly
//! this, so they differ only within a few pixels of shadow edges).

use crate::camera::{PerspectiveCamera, Ray};
use crate::pbr::{self, DirectionalLight, Material, SurfacePoint};
use glam::Vec3;

/// Analytic geometry.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shape {
    /// A sphere.
    Sphere {
        /// Centre (world).
        center: Vec3,
        /// Radius (world units).
        radius: f32,
    },
    /// A finite rectangle, like Bevy's `Plane3d` mesh: centred at `center`, spanning
    /// `±half_size.x` along `u` and `±half_size.y` along `normal × u`. One-sided in the
    /// sense Bevy renders it (back-face culled): rays from behind miss.
    Rect {
        /// Centre (world).
        center: Vec3,
        /// Unit normal (the lit, visible side).
        normal: Vec3,
        /// Unit in-plane axis.
        u: Vec3,
        /// Half extents along `u` and `normal × u`.
        half_size: glam::Vec2,
    },
}

/// A shape with a material.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Object {
    /// Geometry.
    pub shape: Shape,
    /// Shading.
    pub material: Material,
}

/// A ray hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Distance along the ray.
    pub t: f32,
    /// World position.
    pub position: Vec3,
    /// Unit normal facing the ray origin's side.
    pub normal: Vec3,
    /// Index of the object hit.
    pub object: usize,
}

impl Shape {
    /// Nearest intersection with `t` in `(t_min, ∞)`: `(t, normal)`.
    pub fn intersect(&self, ray: &Ray, t_min: f32) -> Option<(f32, Vec3)> {
        match *self {
            Shape::Sphere { center, radius } => {
                let oc = ray.origin - center;
                let b = oc.dot(ray.dir);
                let c = oc.length_squared() - radius * radius;
                let disc = b * b - c;
                if disc < 0.0 {
                    return None;
                }
                let s = disc.sqrt();
                let t = if -b - s > t_min { -b - s } else { -b + s };
                (t > t_min).then(|| (t, (ray.at(t) - center) / radius))
            }
            Shape::Rect {
                center,
                normal,
                u,
                half_size,
            } => {
                let denom = ray.dir.dot(normal);
                if denom >= -1e-8 {
                    return None; // parallel or seen from behind (culled)
                }
                let t = (center - ray.origin).dot(normal) / denom;
                if t <= t_min {
                    return None;
                }
                let d = ray.at(t) - center;
                let v = normal.cross(u);
                (d.dot(u).abs() <= half_size.x && d.dot(v).abs() <= half_size.y)
                    .then_some((t, normal))
            }
        }
    }
}

/// A scene: objects, directional lights, ambient light and background.
#[derive(Clone, Debug, Default)]
pub struct Scene {
    /// Objects.
    pub objects: Vec<Object>,
    /// Directional lights; each casts hard shadows if its flag is set.
    pub lights: Vec<(DirectionalLight, bool)>,
    /// Linear ambient colour × brightness (Bevy's `GlobalAmbientLight`).
    pub ambient: Vec3,
    /// Linear background colour (Bevy's `ClearColor`; not affected by exposure).
    pub background: Vec3,
    /// Camera exposure factor (see [`pbr::exposure_from_ev100`]).
    pub exposure: f32,
}

impl Scene {
    /// The nearest hit along a ray.
    pub fn trace(&self, ray: &Ray) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        for (i, o) in self.objects.iter().enumerate() {
            if let Some((t, n)) = o.shape.intersect(ray, 1e-4)
                && best.is_none_or(|b| t < b.t)
            {
                best = Some(Hit {
                    t,
                    position: ray.at(t),
                    normal: n,
                    object: i,
                });
            }
        }
        best
    }

    /// Whether anything blocks the ray from `p` toward a directional light.
    pub fn occluded(&self, p: Vec3, n: Vec3, dir_to_light: Vec3) -> bool {
        let ray = Ray {
            origin: p + n * 1e-3,
            dir: dir_to_light,
        };
        self.objects
            .iter()
            .any(|o| o.shape.intersect(&ray, 1e-4).is_some())
    }

    /// Linear radiance × exposure seen along a camera ray (the background if it misses).
    pub fn shade(&self, ray: &Ray) -> Vec3 {
        let Some(hit) = self.trace(ray) else {
            return self.background;
        };
        let m = &self.objects[hit.object].material;
        let p = SurfacePoint {
            normal: hit.normal,
            view: -ray.dir,
        };
        let mut radiance = pbr::ambient_radiance(m, &p, self.ambient);
        for (light, shadows) in &self.lights {
            if *shadows && self.occluded(hit.position, hit.normal, light.direction_to_light) {
                continue;
            }
            radiance += pbr::directional_light_radiance(m, &p, light);
        }
        radiance * self.exposure + m.emissive * self.exposure
    }

    /// Renders the scene as an `Rgba8UnormSrgb` target would hold it (alpha 255),
    /// row-major from the top-left pixel.
    pub fn render_srgb8(&self, camera: &PerspectiveCamera) -> Vec<u8> {
        let mut out = Vec::with_capacity((camera.width * camera.height * 4) as usize);
        for y in 0..camera.height {
            for x in 0..camera.width {
                let c = self.shade(&camera.ray(x as f32 + 0.5, y as f32 + 0.5));
                out.extend_from_slice(&pbr::encode_srgb8(c));
                out.push(255);
            }
        }
        out
    }

    /// Renders linear radiance × exposure per pixel (no clamping), row-major.
    pub fn render_linear(&self, camera: &PerspectiveCamera) -> Vec<Vec3> {
        (0..camera.height)
            .flat_map(|y| (0..camera.width).map(move |x| (x, y)))
            .map(|(x, y)| self.shade(&camera.ray(x as f32 + 0.5, y as f32 + 0.5)))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec2;

    fn sphere_on_plane() -> Scene {
        Scene {
            objects: vec![
                Object {
                    shape: Shape::Sphere {
                        center: Vec3::new(0.0, 1.0, 0.0),
                        radius: 1.0,
                    },
                    material: Material::default(),
                },
                Object {
                    shape: Shape::Rect {
                        center: Vec3::ZERO,
                        normal: Vec3::Y,
                        u: Vec3::X,
                        half_size: Vec2::splat(10.0),
                    },
                    material: Material::default(),
                },
            ],
            lights: vec![(
                DirectionalLight {
                    direction_to_light: Vec3::Y,
                    color_lux: Vec3::splat(1000.0),
                },
                true,
            )],
            ambient: Vec3::ZERO,
            background: Vec3::new(0.1, 0.2, 0.3),
            exposure: 1e-3,
        }
    }

    #[test]
    fn sphere_hit_distance_and_normal_are_exact() {
        let s = Shape::Sphere {
            center: Vec3::new(0.0, 0.0, -5.0),
            radius: 2.0,
        };
        let ray = Ray {
            origin: Vec3::ZERO,
            dir: -Vec3::Z,
        };
        let (t, n) = s.intersect(&ray, 0.0).unwrap();
        assert!((t - 3.0).abs() < 1e-6);
        assert!((n - Vec3::Z).length() < 1e-6);
        let miss = Ray {
            origin: Vec3::new(2.01, 0.0, 0.0),
            dir: -Vec3::Z,
        };
        assert!(s.intersect(&miss, 0.0).is_none());
    }

    #[test]
    fn rect_is_finite_and_back_face_culled() {
        let r = Shape::Rect {
            center: Vec3::ZERO,
            normal: Vec3::Y,
            u: Vec3::X,
            half_size: Vec2::new(1.0, 2.0),
        };
        let down = |x: f32, z: f32| Ray {
            origin: Vec3::new(x, 3.0, z),
            dir: -Vec3::Y,
        };
        assert!(r.intersect(&down(0.9, 1.9), 0.0).is_some());
        assert!(r.intersect(&down(1.1, 0.0), 0.0).is_none());
        assert!(r.intersect(&down(0.0, 2.1), 0.0).is_none());
        let up = Ray {
            origin: Vec3::new(0.0, -3.0, 0.0),
            dir: Vec3::Y,
        };
        assert!(r.intersect(&up, 0.0).is_none());
    }

    #[test]
    fn shadow_under_sphere_and_lit_elsewhere() {
        let scene = sphere_on_plane();
        let lit = |x: f32| {
            let ray = Ray {
                origin: Vec3::new(x, 5.0, 3.0),
                dir: Vec3::new(0.0, -5.0, -3.0).normalize(),
            };
            scene.shade(&ray)
        };
        // Straight under the sphere (overhead light): shadowed, ambient 0 → black.
        let under = Ray {
            origin: Vec3::new(0.0, 0.2, 3.0),
            dir: Vec3::new(0.0, -0.2, -2.5).normalize(),
        };
        assert_eq!(scene.trace(&under).unwrap().object, 1);
        assert_eq!(scene.shade(&under), Vec3::ZERO);
        assert!(lit(3.0).x > 0.1);
        // Missing everything gives the background.
        let sky = Ray {
            origin: Vec3::new(0.0, 5.0, 0.0),
            dir: Vec3::Y,
        };
        assert_eq!(scene.shade(&sky), scene.background);
    }
}
