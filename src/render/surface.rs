//! A scene's surfaces: one material everywhere ([`Surface::Uniform`]) or a material map
//! over the object's texture coordinates ([`Surface::Textured`]), and what either is at
//! one hit point and a path's four wavelengths ([`SurfacePoint`]), which the integrator
//! samples by one rule for both (model.md §6).
//!
//! A textured surface shares each fluorophore's tables between all texels, built at unit
//! concentration (k = Q, or Φ in the photon form): a texel with concentrations c_k has
//! the fluorescent term Σ c_k·Q_k·x_k(λi)·a_k(λi)·e_k(λo), so every quantity of the
//! sampling that scales with k scales with c_k (the fluorophore's share of the
//! fluorescent albedo, of the lit albedo), while the excitation samplers, which depend
//! on a_k and the light alone, are the same for every texel. The diagonal
//! (1 − Σ c_k·a_k(λ))·r(λ) is evaluated at the point from the interpolated c_k and r.
//! [`MaterialSource`] is what a built-in scene shows: a [`Material`] or a
//! [`MaterialTexture`].

use glam::{Vec3, Vec4};

use crate::error::Result;
use crate::material::Material;

use super::geometry::Shape;
use super::spectra::{FluorophoreTables, LAMBDA_MIN_NM, Lookup, SurfaceTables, Table};
use super::texture::{Footprint, MaterialTexture};

/// What the main object of a built-in scene is made of.
#[derive(Debug, Clone, Copy)]
pub enum MaterialSource<'a> {
    /// One material everywhere.
    Uniform(&'a Material),
    /// A material map over the object's texture coordinates.
    Map(&'a MaterialTexture),
}

impl<'a> From<&'a Material> for MaterialSource<'a> {
    fn from(material: &'a Material) -> Self {
        MaterialSource::Uniform(material)
    }
}

impl<'a> From<&'a MaterialTexture> for MaterialSource<'a> {
    fn from(texture: &'a MaterialTexture) -> Self {
        MaterialSource::Map(texture)
    }
}

impl MaterialSource<'_> {
    /// The material's or the map's name.
    pub fn name(&self) -> &str {
        match self {
            MaterialSource::Uniform(m) => &m.name,
            MaterialSource::Map(t) => &t.name,
        }
    }

    /// Its surface (a material is checked first with [`Material::validate`]).
    pub fn surface(&self) -> Result<Surface> {
        Ok(match self {
            MaterialSource::Uniform(m) => Surface::Uniform(SurfaceTables::new(m)?),
            MaterialSource::Map(t) => Surface::Textured(TexturedSurface::new(t, true)),
        })
    }

    /// The surface with the same reflectance and no fluorescence (c = 0), for
    /// `--compare`'s twin.
    pub fn twin(&self) -> Result<Surface> {
        Ok(match self {
            MaterialSource::Uniform(m) => {
                let plain = Material::new(
                    format!("{} without fluorescence", m.name),
                    m.reflectance.clone(),
                    Vec::new(),
                );
                Surface::Uniform(SurfaceTables::new(&plain)?)
            }
            MaterialSource::Map(t) => Surface::Textured(TexturedSurface::new(t, false)),
        })
    }

    /// Width / height of what the texture coordinates span: the map's texels, 1 for a
    /// uniform material.
    pub fn aspect(&self) -> f32 {
        match self {
            MaterialSource::Uniform(_) => 1.0,
            MaterialSource::Map(t) => t.aspect(),
        }
    }
}

/// A material map's surface: the map's textures and its fluorophores' tables at unit
/// concentration.
#[derive(Debug, Clone)]
pub struct TexturedSurface {
    /// A short name for messages.
    pub name: String,
    texture: MaterialTexture,
    /// a_k(λ) of every fluorophore of the map, for the diagonal.
    absorption: Vec<Table>,
    /// The fluorophores that may fire, at unit concentration (k = Q or Φ).
    fluorophores: Vec<FluorophoreTables>,
    /// The map's fluorophore (texture channel) of each of `fluorophores`.
    channels: Vec<usize>,
}

impl TexturedSurface {
    /// The surface of `texture`; without `fluorescent`, its reflectance alone (c = 0).
    pub fn new(texture: &MaterialTexture, fluorescent: bool) -> TexturedSurface {
        let mut absorption = Vec::new();
        let mut fluorophores = Vec::new();
        let mut channels = Vec::new();
        if fluorescent {
            for (k, f) in texture.fluorophores.iter().enumerate() {
                absorption.push(Table::from_fn(|nm| f.absorption.eval_zero_outside(nm)));
                let unit = crate::material::Fluorophore {
                    concentration: 1.0,
                    ..f.clone()
                };
                let tables = FluorophoreTables::new(&unit);
                if tables.fires() && texture.mean_concentration(k) > 0.0 {
                    fluorophores.push(tables);
                    channels.push(k);
                }
            }
        }
        TexturedSurface {
            name: if fluorescent {
                texture.name.clone()
            } else {
                format!("{} without fluorescence", texture.name)
            },
            texture: texture.clone(),
            absorption,
            fluorophores,
            channels,
        }
    }

    /// The radiance the map sends on average in a furnace of the light `light`: the
    /// mean diagonal d̄ = r̄ − Σ a_k·(c_k·r)‾ times L plus the mean lit albedo Σ c̄_k·G_k,
    /// at the 1 nm nodes (a guide for the camera's wavelengths).
    fn furnace_guide(&self, light: &Table) -> Table {
        let mut values = Vec::with_capacity(light.values.len());
        for (i, l) in light.values.iter().enumerate() {
            let nm = LAMBDA_MIN_NM + i as f32;
            let (r, absorbing) = self.texture.mean_at(nm);
            let absorbed: f32 = self
                .absorption
                .iter()
                .zip(&absorbing)
                .map(|(a, cr)| a.values[i] * cr)
                .sum();
            let mut value = (r - absorbed).max(0.0) * l;
            for (f, &k) in self.fluorophores.iter().zip(&self.channels) {
                if let Some(lit) = &f.lit {
                    value += self.texture.mean_concentration(k)
                        * f.k
                        * lit.absorbed
                        * f.emission.values[i];
                }
            }
            values.push(value);
        }
        Table::from_values(values)
    }

    /// The surface at `point` on `shape`, at the wavelengths of `at` (`nm`).
    #[inline]
    fn at(&self, shape: &Shape, point: Vec3, at: &Lookup, nm: Vec4) -> SurfacePoint<'_> {
        let (u, v) = shape.uv_at(point);
        let footprint = self.texture.footprint(u, v, shape.uv_wraps());
        let mut absorbed = Vec4::ZERO;
        for (k, a) in self.absorption.iter().enumerate() {
            let c = self.texture.concentration(&footprint, k);
            if c > 0.0 {
                absorbed += c * a.gather(at);
            }
        }
        let reflectance = self.texture.reflectance(&footprint, nm);
        let diagonal = (Vec4::ONE - absorbed).max(Vec4::ZERO) * reflectance;
        let mut fluorescent = Vec4::ZERO;
        let mut lit = Vec4::ZERO;
        let mut any = false;
        for (f, &k) in self.fluorophores.iter().zip(&self.channels) {
            let c = self.texture.concentration(&footprint, k);
            if c > 0.0 {
                any = true;
                fluorescent += c * f.albedo.gather(at);
                if let Some(l) = &f.lit {
                    lit += (c * f.k * l.absorbed) * f.emission.gather(at);
                }
            }
        }
        SurfacePoint {
            diagonal,
            fluorescent_albedo: fluorescent,
            lit_albedo: lit,
            fluorophores: if any { &self.fluorophores } else { &[] },
            scales: Scales::Texel {
                texture: &self.texture,
                footprint,
                channels: &self.channels,
            },
        }
    }
}

/// A surface of a scene.
#[derive(Debug, Clone)]
pub enum Surface {
    /// One material everywhere.
    Uniform(SurfaceTables),
    /// A material map over the object's texture coordinates.
    Textured(TexturedSurface),
}

impl From<SurfaceTables> for Surface {
    fn from(tables: SurfaceTables) -> Self {
        Surface::Uniform(tables)
    }
}

impl From<TexturedSurface> for Surface {
    fn from(surface: TexturedSurface) -> Self {
        Surface::Textured(surface)
    }
}

impl Surface {
    /// A short name for messages.
    pub fn name(&self) -> &str {
        match self {
            Surface::Uniform(t) => &t.name,
            Surface::Textured(t) => &t.name,
        }
    }

    /// Builds the light-aware excitation samplers for a scene whose every emitter shares
    /// the spectrum `light` (see [`SurfaceTables::light_with`]).
    pub fn light_with(&mut self, light: &Table) {
        match self {
            Surface::Uniform(t) => t.light_with(light),
            Surface::Textured(t) => {
                for f in &mut t.fluorophores {
                    f.light_with(light);
                }
            }
        }
    }

    /// The radiance the surface sends in a furnace of `light` at the 1 nm nodes, d·L + G
    /// (a map's mean), which guides the camera's wavelengths.
    pub fn furnace_guide(&self, light: &Table) -> Table {
        match self {
            Surface::Uniform(surface) => Table::from_values(
                light
                    .values()
                    .iter()
                    .zip(surface.diagonal.values())
                    .zip(surface.lit_albedo.values())
                    .map(|((l, d), g)| d * l + g)
                    .collect(),
            ),
            Surface::Textured(t) => t.furnace_guide(light),
        }
    }

    /// The surface at `point` on `shape`, at the four wavelengths `nm` (looked up as
    /// `at`). A uniform surface ignores the point.
    #[inline]
    pub fn at(&self, shape: &Shape, point: Vec3, at: &Lookup, nm: Vec4) -> SurfacePoint<'_> {
        match self {
            Surface::Uniform(t) => {
                let fluorescent = t.is_fluorescent();
                SurfacePoint {
                    diagonal: t.diagonal.gather(at),
                    fluorescent_albedo: if fluorescent {
                        t.fluorescent_albedo.gather(at)
                    } else {
                        Vec4::ZERO
                    },
                    lit_albedo: if fluorescent {
                        t.lit_albedo.gather(at)
                    } else {
                        Vec4::ZERO
                    },
                    fluorophores: &t.fluorophores,
                    scales: Scales::One,
                }
            }
            Surface::Textured(t) => t.at(shape, point, at, nm),
        }
    }
}

/// How a point's fluorophores scale the tables' k.
#[derive(Debug, Clone, Copy)]
enum Scales<'s> {
    /// Not at all: a uniform material's tables hold its own k.
    One,
    /// By the concentrations interpolated at the point.
    Texel {
        texture: &'s MaterialTexture,
        footprint: Footprint,
        channels: &'s [usize],
    },
}

/// A surface at one point and four wavelengths: what a camera path samples there.
#[derive(Debug, Clone, Copy)]
pub struct SurfacePoint<'s> {
    /// d(λ) at the four wavelengths.
    pub diagonal: Vec4,
    /// F(λo) = Σ k·A·e(λo) at the four wavelengths (zero without fluorescence).
    pub fluorescent_albedo: Vec4,
    /// G(λo) = Σ k·B·e(λo) under the scene's light at the four wavelengths.
    pub lit_albedo: Vec4,
    /// The fluorophores that may fire here (empty when none does), with k of
    /// fluorophore j at this point = [`SurfacePoint::scale`]`(j)` × its tables' k.
    pub fluorophores: &'s [FluorophoreTables],
    scales: Scales<'s>,
}

impl<'s> SurfacePoint<'s> {
    /// True when some fluorophore may fire here.
    #[inline]
    pub fn is_fluorescent(&self) -> bool {
        !self.fluorophores.is_empty()
    }

    /// The factor of fluorophore `j`'s k here: 1 for a uniform material, the
    /// concentration at the point for a map (whose tables hold unit concentration).
    #[inline]
    pub fn scale(&self, j: usize) -> f32 {
        match &self.scales {
            Scales::One => 1.0,
            Scales::Texel {
                texture,
                footprint,
                channels,
            } => texture.concentration(footprint, channels[j]),
        }
    }

    /// The fluorophore an event falls back on when rounding leaves the draw past every
    /// share: the last one that may fire here (with `lit`, whose light-aware sampler
    /// exists), else the first. Call only when [`SurfacePoint::is_fluorescent`].
    #[inline]
    pub fn fallback(&self, lit: bool) -> &'s FluorophoreTables {
        let fluorophores = self.fluorophores;
        let usable = |j: usize| {
            (!lit || fluorophores[j].lit.is_some())
                && (matches!(self.scales, Scales::One) || self.scale(j) > 0.0)
        };
        let last = (0..fluorophores.len()).rev().find(|&j| usable(j));
        match (lit, last) {
            (_, Some(j)) => &fluorophores[j],
            (true, None) => &fluorophores[0],
            (false, None) => &fluorophores[fluorophores.len() - 1],
        }
    }
}
