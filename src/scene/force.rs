//! Force fields on garments (`forces[]`): wind with aerodynamic drag on the cloth's faces, and
//! point attractors (or repellers). What each field means and its units; the physics is in
//! `sim::forces`.

use serde::{Deserialize, Serialize};

/// One force field.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields, tag = "kind", rename_all = "snake_case")]
pub enum ForceSpec {
    Wind(WindSpec),
    Attractor(AttractorSpec),
}

/// Wind: air moving at `velocity`, pressing on every face of the garments (grid garments:
/// sheets, ponchos, curtains, flags) in proportion to the air's speed relative to the face.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct WindSpec {
    /// Air velocity [m/s] (when `keyframes` is empty). Default `[0, 0, 0]`.
    pub velocity: [f32; 3],
    /// Air density ρ [kg/m³]. Default 1.2 (air at 20 °C).
    pub density: f32,
    /// Pressure coefficient C_n of a face across the flow: the force along the face's normal is
    /// ½ ρ C_n A |v| (v·n) (its component along the flow is the face's drag, across the flow
    /// its lift). Default 1.0 (about a flat plate's).
    pub drag: f32,
    /// Skin friction coefficient C_t along the face: ½ ρ C_t A |v| v_t. Default 0.02.
    pub friction: f32,
    /// Air velocity over time, linear between keys (before the first and after the last, the
    /// nearest); replaces `velocity`.
    pub keyframes: Vec<WindKey>,
    /// Gusts: smooth, seeded noise in space and time added to the velocity.
    pub turbulence: Option<TurbulenceSpec>,
}

impl Default for WindSpec {
    fn default() -> Self {
        WindSpec {
            velocity: [0.0; 3],
            density: 1.2,
            drag: 1.0,
            friction: 0.02,
            keyframes: Vec::new(),
            turbulence: None,
        }
    }
}

impl ForceSpec {
    /// Moves every keyframe `seconds` later (a pre-roll before the shot's first frame).
    pub fn delay(&mut self, seconds: f32) {
        if let ForceSpec::Wind(w) = self {
            w.keyframes.iter_mut().for_each(|k| k.time += seconds);
        }
    }
}

/// The wind's velocity at one time.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct WindKey {
    /// Seconds from the start of the bake.
    pub time: f32,
    /// Air velocity [m/s].
    pub velocity: [f32; 3],
}

/// Gusts: a sum of a few travelling waves with seeded directions, lengths and phases, as smooth
/// in space and time as the wind itself.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct TurbulenceSpec {
    /// Largest speed the gusts add [m/s]. Default 1.
    pub strength: f32,
    /// Size of a gust [m]. Default 1.
    pub scale: f32,
    /// Time a gust takes to come and go [s]. Default 1.
    pub period: f32,
    /// Another seed, other gusts. Default 0.
    pub seed: u32,
}

impl Default for TurbulenceSpec {
    fn default() -> Self {
        TurbulenceSpec {
            strength: 1.0,
            scale: 1.0,
            period: 1.0,
            seed: 0,
        }
    }
}

/// A point that pulls every garment particle towards it (or, with a negative strength, pushes
/// away), fading to nothing at `radius`.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct AttractorSpec {
    /// Where [m].
    pub position: [f32; 3],
    /// Acceleration towards the point at the point itself [m/s²]; negative repels.
    /// Default 1.
    pub strength: f32,
    /// Distance at which the pull has faded to zero [m], as (1 − (d/radius)²)². Default 1.
    pub radius: f32,
}

impl Default for AttractorSpec {
    fn default() -> Self {
        AttractorSpec {
            position: [0.0; 3],
            strength: 1.0,
            radius: 1.0,
        }
    }
}

/// The most force fields in one scene (each is evaluated for every particle every substep).
pub const MAX_FORCES: usize = 64;

/// Checks one force field; the error names the field (relative to the force) and the reason.
pub fn validate(force: &ForceSpec) -> Result<(), (String, String)> {
    let finite = |name: &str, v: &[f32]| {
        if v.iter().all(|x| x.is_finite() && x.abs() <= 1e5) {
            Ok(())
        } else {
            Err((name.to_string(), "must be finite and within ±1e5".into()))
        }
    };
    let positive = |name: &str, v: f32| {
        if v.is_finite() && v > 0.0 && v <= 1e5 {
            Ok(())
        } else {
            Err((
                name.to_string(),
                format!("must be above 0 (and at most 1e5), not {v}"),
            ))
        }
    };
    let non_negative = |name: &str, v: f32| {
        if v.is_finite() && (0.0..=1e5).contains(&v) {
            Ok(())
        } else {
            Err((
                name.to_string(),
                format!("must be 0 or more (and at most 1e5), not {v}"),
            ))
        }
    };
    match force {
        ForceSpec::Wind(w) => {
            finite("velocity", &w.velocity)?;
            non_negative("density", w.density)?;
            non_negative("drag", w.drag)?;
            non_negative("friction", w.friction)?;
            let mut last = f32::NEG_INFINITY;
            for (k, key) in w.keyframes.iter().enumerate() {
                finite(&format!("keyframes[{k}].velocity"), &key.velocity)?;
                if !key.time.is_finite() || key.time < 0.0 || key.time <= last {
                    return Err((
                        format!("keyframes[{k}].time"),
                        "times must be finite, 0 or more, and increasing".into(),
                    ));
                }
                last = key.time;
            }
            if let Some(t) = &w.turbulence {
                non_negative("turbulence.strength", t.strength)?;
                positive("turbulence.scale", t.scale)?;
                positive("turbulence.period", t.period)?;
            }
        }
        ForceSpec::Attractor(a) => {
            finite("position", &a.position)?;
            finite("strength", &[a.strength])?;
            positive("radius", a.radius)?;
        }
    }
    Ok(())
}
