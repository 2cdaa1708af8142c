//! The illumination model at one surface point (lecture, Unit 5, "Basic Illumination
//! Models"): ambient ka·Ia, Lambert diffuse kd·Il·(N·L), Phong specular ks·Il·(V·R)^ns or
//! its halfway-vector form ks·Il·(N·H)^ns, summed over the lights:
//!
//! I = ka·Ia + Σ Il_i [kd (N·L_i) + ks (N·H_i)^ns]
//!
//! Every quantity is linear-light RGB and the model is applied per channel, so a surface's
//! colour filters the light's colour: a red ball under green light is black, under magenta
//! light red (the lecture's "Effect of Light Source on color of object" table).

use super::geometry::{reflect, Vec3};

/// A linear-light RGB triple (0 = no light, 1 = full intensity; may exceed 1 before output).
pub type Rgb = Vec3;

/// Which form of the Phong specular term a material uses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Highlight {
    /// ks·Il·(N·H)^ns with H the halfway vector between L and V (the lecture's combined form).
    #[default]
    Halfway,
    /// ks·Il·(V·R)^ns with R the mirror direction of L (Phong's original form).
    Reflection,
}

/// The optical properties of a surface.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// The surface colour: the fraction of each channel it reflects diffusely.
    pub color: Rgb,
    /// Ambient-reflection coefficient ka (0..1), scaled per channel by `color`.
    pub ka: f64,
    /// Diffuse-reflection coefficient kd (0..1), scaled per channel by `color`.
    pub kd: f64,
    /// Specular-reflection coefficient ks (0..1).
    pub ks: f64,
    /// Specular-reflection parameter ns: near 1 dull, 100 or more shiny.
    pub ns: f64,
    /// Colour of the highlight (white for plastics, the surface colour for metals).
    pub specular_color: Rgb,
    /// Which specular form to use.
    pub highlight: Highlight,
    /// Fraction of the mirror-direction ray added by the ray tracer (0 = none).
    pub reflect: f64,
    /// Fraction of the refracted ray added by the ray tracer (0 = opaque).
    pub transmit: f64,
    /// Index of refraction η of the material (1.5 for glass).
    pub ior: f64,
}

impl Default for Material {
    fn default() -> Self {
        Material {
            color: Rgb::new(1.0, 1.0, 1.0),
            ka: 0.1,
            kd: 0.7,
            ks: 0.3,
            ns: 20.0,
            specular_color: Rgb::new(1.0, 1.0, 1.0),
            highlight: Highlight::Halfway,
            reflect: 0.0,
            transmit: 0.0,
            ior: 1.0,
        }
    }
}

/// Warn's studio light (lecture, Unit 5, "Warn Model"): a point source pointing along an
/// axis whose intensity falls off as cos^p of the angle from that axis (a Phong exponent
/// applied to the light), cut to a cone, with flaps (barn doors) bounding the lit region.
#[derive(Clone, Debug, PartialEq)]
pub struct WarnLight {
    /// Where the source is.
    pub position: Vec3,
    /// The unit direction it points in.
    pub direction: Vec3,
    /// The Phong exponent of the source: larger means a tighter beam.
    pub exponent: f64,
    /// Half-angle of the spotlight cone in radians (`None` = no cone).
    pub cone: Option<f64>,
    /// Flaps: for x, y and z, the range of scene coordinates the light reaches (`None` = open).
    pub flaps: [Option<[f64; 2]>; 3],
}

/// The kinds of light source.
#[derive(Clone, Debug, PartialEq)]
pub enum LightKind {
    /// Rays diverge from a point: the direction to the light changes across a surface.
    Point {
        /// Where the source is.
        position: Vec3,
    },
    /// All rays parallel, no point of origin (sunlight).
    Directional {
        /// The unit direction the light travels in.
        direction: Vec3,
    },
    /// A Warn studio light.
    Warn(WarnLight),
}

/// A light source: its kind, colour/intensity Il, and distance attenuation.
#[derive(Clone, Debug, PartialEq)]
pub struct Light {
    /// The kind of source and its placement.
    pub kind: LightKind,
    /// The intensity Il per channel.
    pub color: Rgb,
    /// Radial attenuation f(d) = 1 / (a0 + a1·d + a2·d²), capped at 1; `[1, 0, 0]` = none.
    /// Ignored for directional lights.
    pub attenuation: [f64; 3],
}

/// Light arriving at a surface point from one source.
#[derive(Clone, Copy, Debug)]
pub struct Incidence {
    /// Unit vector from the point towards the light (L).
    pub l: Vec3,
    /// Distance to the light (infinite for a directional light).
    pub distance: f64,
    /// Intensity arriving, after attenuation, cone and flaps.
    pub intensity: Rgb,
}

impl Light {
    /// A white point light of unit intensity without attenuation.
    pub fn point(position: Vec3, color: Rgb) -> Light {
        Light {
            kind: LightKind::Point { position },
            color,
            attenuation: [1.0, 0.0, 0.0],
        }
    }

    /// A directional light travelling along `direction`.
    pub fn directional(direction: Vec3, color: Rgb) -> Light {
        Light {
            kind: LightKind::Directional {
                direction: direction.normalized(),
            },
            color,
            attenuation: [1.0, 0.0, 0.0],
        }
    }

    /// The light reaching point `p`, or `None` if none does (outside a cone or flap).
    #[inline]
    pub fn incidence(&self, p: Vec3) -> Option<Incidence> {
        let atten = |d: f64| {
            let [a0, a1, a2] = self.attenuation;
            (1.0 / (a0 + a1 * d + a2 * d * d)).min(1.0)
        };
        match &self.kind {
            LightKind::Directional { direction } => Some(Incidence {
                l: -*direction,
                distance: f64::INFINITY,
                intensity: self.color,
            }),
            LightKind::Point { position } => {
                let to = *position - p;
                let d = to.length();
                Some(Incidence {
                    l: to / d,
                    distance: d,
                    intensity: self.color * atten(d),
                })
            }
            LightKind::Warn(w) => {
                for (axis, flap) in w.flaps.iter().enumerate() {
                    if let Some([lo, hi]) = flap {
                        let c = p.get(axis);
                        if c < *lo || c > *hi {
                            return None;
                        }
                    }
                }
                let to = w.position - p;
                let d = to.length();
                let l = to / d;
                // Angle γ between the light's axis and the ray from the light to the point.
                let cos_g = w.direction.dot(-l);
                if cos_g <= 0.0 {
                    return None;
                }
                if let Some(cone) = w.cone {
                    if cos_g < cone.cos() {
                        return None;
                    }
                }
                Some(Incidence {
                    l,
                    distance: d,
                    intensity: self.color * (cos_g.powf(w.exponent) * atten(d)),
                })
            }
        }
    }
}

/// The intensity leaving point `p` with unit normal `n` towards the viewer along unit `v`,
/// under ambient light `ambient` and `lights`. `shadow(p, incidence)` returns the fraction of
/// that light that is not blocked (1 for no shadows).
#[inline]
pub fn illuminate(
    m: &Material,
    p: Vec3,
    n: Vec3,
    v: Vec3,
    ambient: Rgb,
    lights: &[Light],
    mut shadow: impl FnMut(Vec3, &Incidence) -> f64,
) -> Rgb {
    let diffuse = m.color * m.kd;
    let mut sum = m.color.mul_elem(ambient) * m.ka;
    for light in lights {
        let Some(inc) = light.incidence(p) else {
            continue;
        };
        let n_dot_l = n.dot(inc.l);
        if n_dot_l <= 0.0 {
            continue; // the light is behind the surface
        }
        let spec = if m.ks > 0.0 {
            let c = match m.highlight {
                Highlight::Halfway => n.dot((inc.l + v).normalized()),
                // R is the mirror of L about N: reflect(−L) = 2(N·L)N − L.
                Highlight::Reflection => v.dot(reflect(-inc.l, n)),
            };
            if c > 0.0 {
                m.ks * c.powf(m.ns)
            } else {
                0.0
            }
        } else {
            0.0
        };
        let reflected = inc
            .intensity
            .mul_elem(diffuse * n_dot_l + m.specular_color * spec);
        if reflected.max_elem() <= 0.0 {
            continue; // nothing reflected: no need to trace the shadow ray
        }
        let pass = shadow(p, &inc);
        if pass > 0.0 {
            sum += reflected * pass;
        }
    }
    sum
}

#[cfg(test)]
mod tests {
    use super::*;

    const WHITE: Rgb = Rgb::new(1.0, 1.0, 1.0);
    const RED: Rgb = Rgb::new(1.0, 0.0, 0.0);
    const GREEN: Rgb = Rgb::new(0.0, 1.0, 0.0);
    const BLUE: Rgb = Rgb::new(0.0, 0.0, 1.0);
    const MAGENTA: Rgb = Rgb::new(1.0, 0.0, 1.0);
    const YELLOW: Rgb = Rgb::new(1.0, 1.0, 0.0);
    const CYAN: Rgb = Rgb::new(0.0, 1.0, 1.0);

    fn lit(m: &Material, light: Rgb) -> Rgb {
        let n = Vec3::new(0.0, 0.0, 1.0);
        let lights = [Light::directional(-n, light)];
        illuminate(m, Vec3::ZERO, n, n, Rgb::ZERO, &lights, |_, _| 1.0)
    }

    fn close(a: Rgb, b: Rgb) -> bool {
        (a - b).length() < 1e-9
    }

    #[test]
    fn lecture_ball_and_light_table() {
        // Lecture, Unit 5, "Effect of Light Source on color of object": ball, light, image.
        let ball = |color| Material {
            color,
            ka: 0.0,
            kd: 1.0,
            ks: 0.0,
            ..Material::default()
        };
        assert!(close(lit(&ball(WHITE), RED), RED));
        assert!(close(lit(&ball(RED), WHITE), RED));
        assert!(close(lit(&ball(RED), GREEN), Rgb::ZERO));
        assert!(close(lit(&ball(MAGENTA), BLUE), BLUE));
        assert!(close(lit(&ball(YELLOW), CYAN), GREEN));
        // And from the slides before it: red ball in magenta light is red.
        assert!(close(lit(&ball(RED), MAGENTA), RED));
    }

    #[test]
    fn lambert_cosine_and_ambient() {
        let m = Material {
            ka: 0.3,
            kd: 0.4,
            ks: 0.0,
            ..Material::default()
        };
        let n = Vec3::new(0.0, 0.0, 1.0);
        let a = 60f64.to_radians();
        let lights = [Light::directional(
            Vec3::new(-a.sin(), 0.0, -a.cos()),
            WHITE,
        )];
        let i = illuminate(&m, Vec3::ZERO, n, n, WHITE, &lights, |_, _| 1.0);
        // ka·Ia + kd·Il·cos 60° = 0.3 + 0.4·0.5
        assert!(close(i, WHITE * 0.5));
        // Behind the surface: ambient only.
        let lights = [Light::directional(n, WHITE)];
        let i = illuminate(&m, Vec3::ZERO, n, n, WHITE, &lights, |_, _| 1.0);
        assert!(close(i, WHITE * 0.3));
    }

    #[test]
    fn specular_forms_agree_at_the_mirror_angle_and_sum_over_lights() {
        let n = Vec3::new(0.0, 0.0, 1.0);
        let a = 30f64.to_radians();
        let l = Vec3::new(a.sin(), 0.0, a.cos());
        let v = Vec3::new(-a.sin(), 0.0, a.cos()); // exactly along R
        let lights = [Light::directional(-l, WHITE)];
        for highlight in [Highlight::Halfway, Highlight::Reflection] {
            let m = Material {
                ka: 0.0,
                kd: 0.0,
                ks: 0.5,
                ns: 50.0,
                highlight,
                ..Material::default()
            };
            let i = illuminate(&m, Vec3::ZERO, n, v, Rgb::ZERO, &lights, |_, _| 1.0);
            assert!(close(i, WHITE * 0.5), "{highlight:?}: {i:?}");
            // Off the mirror angle, the shinier the faster it falls.
            let v2 = Vec3::new(0.0, 0.0, 1.0);
            let dull = illuminate(
                &Material {
                    ns: 2.0,
                    ..m.clone()
                },
                Vec3::ZERO,
                n,
                v2,
                Rgb::ZERO,
                &lights,
                |_, _| 1.0,
            );
            let shiny = illuminate(&m, Vec3::ZERO, n, v2, Rgb::ZERO, &lights, |_, _| 1.0);
            assert!(shiny.x < dull.x && shiny.x > 0.0);
        }
        // Two lights add.
        let m = Material {
            ka: 0.0,
            kd: 0.5,
            ks: 0.0,
            ..Material::default()
        };
        let two = [Light::directional(-n, RED), Light::directional(-n, BLUE)];
        let i = illuminate(&m, Vec3::ZERO, n, n, Rgb::ZERO, &two, |_, _| 1.0);
        assert!(close(i, MAGENTA * 0.5));
    }

    #[test]
    fn point_light_direction_varies_and_attenuates() {
        let mut light = Light::point(Vec3::new(0.0, 0.0, 2.0), WHITE);
        let a = light.incidence(Vec3::ZERO).unwrap();
        let b = light.incidence(Vec3::new(2.0, 0.0, 0.0)).unwrap();
        assert!(close(a.l, Vec3::new(0.0, 0.0, 1.0)));
        assert!(a.l.dot(b.l) < 0.8);
        light.attenuation = [0.0, 0.0, 1.0];
        let a = light.incidence(Vec3::new(0.0, 0.0, -2.0)).unwrap();
        assert!((a.intensity.x - 1.0 / 16.0).abs() < 1e-12);
    }

    #[test]
    fn warn_light_cone_exponent_and_flaps() {
        let light = Light {
            kind: LightKind::Warn(WarnLight {
                position: Vec3::new(0.0, 10.0, 0.0),
                direction: Vec3::new(0.0, -1.0, 0.0),
                exponent: 4.0,
                cone: Some(30f64.to_radians()),
                flaps: [Some([-3.0, 2.0]), None, None],
            }),
            color: WHITE,
            attenuation: [1.0, 0.0, 0.0],
        };
        let on_axis = light.incidence(Vec3::ZERO).unwrap();
        assert!(close(on_axis.intensity, WHITE));
        // 1.5 off axis at distance 10: inside the cone, dimmed by cos^4.
        let p = Vec3::new(1.5, 0.0, 0.0);
        let off = light.incidence(p).unwrap();
        let cos_g = 10.0 / (100.0f64 + 2.25).sqrt();
        assert!((off.intensity.x - cos_g.powi(4)).abs() < 1e-12);
        // Past the barn door at x = 2, and outside the 30° cone on the other side.
        assert!(light.incidence(Vec3::new(2.5, 0.0, 0.0)).is_none());
        assert!(light.incidence(Vec3::new(0.0, 0.0, 6.0)).is_none());
        assert!(light.incidence(Vec3::new(0.0, 0.0, 5.0)).is_some());
    }
}
