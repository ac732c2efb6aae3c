//! The model kind as data: a tagged config recorded in `config.json` and in every
//! checkpoint, and the one function that builds a representation from it.
//!
//! JSON: `"model": {"kind": "saro", "hidden": 64, ...}`; a config without `kind` is
//! read as `saro` (configs written before the kind existed). Any other kind is a
//! representation a program registers under that name (`maaf::cli::Maaf::representation`,
//! docs/extending.md): its options are the section's other keys, kept as JSON for
//! its factory to read ([`ModelConfig::options`]).

use serde::{Deserialize, Deserializer, Serialize, Serializer};

use super::{
    DeformConfig, DeformModel, PointCloud, Representation, SaroConfig, SaroModel, TrackConfig,
    TrackModel,
};

/// Which representation to train, with its settings (`--model`).
#[derive(Clone, Debug, PartialEq)]
pub enum ModelConfig {
    /// SaRO-GS (Sec. 3.2 of the paper): 4D Gaussians plus a scale-aware residual field.
    Saro(SaroConfig),
    /// Deformable 3D Gaussians (Yang et al. 2024): canonical Gaussians plus a
    /// deformation MLP on the encoded centre and time (the paper's plug-in base).
    Deform(DeformConfig),
    /// Dynamic 3D Gaussians (Luiten et al. 2024): a centre and a rotation per frame,
    /// trained frame by frame with neighbour rigidity terms (`models/src/track`).
    Track(TrackConfig),
    /// A representation registered by name by the program that trains it, with its
    /// own options (the `model` section's keys other than `kind`), which its factory
    /// reads and validates.
    Custom {
        /// The registered name (the representation's `name()`).
        kind: String,
        /// Its options as JSON.
        options: serde_json::Map<String, serde_json::Value>,
    },
}

impl Default for ModelConfig {
    fn default() -> Self {
        ModelConfig::Saro(SaroConfig::default())
    }
}

impl<'de> Deserialize<'de> for ModelConfig {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(tag = "kind", rename_all = "lowercase")]
        enum Tagged {
            Saro(SaroConfig),
            Deform(DeformConfig),
            Track(TrackConfig),
        }
        let mut value = serde_json::Value::deserialize(d)?;
        if let Some(obj) = value.as_object_mut() {
            match obj.get("kind") {
                None => {
                    obj.insert("kind".into(), "saro".into());
                }
                Some(serde_json::Value::String(k)) if !Self::KINDS.contains(&k.as_str()) => {
                    let kind = k.clone();
                    let mut options = obj.clone();
                    options.remove("kind");
                    return Ok(ModelConfig::Custom { kind, options });
                }
                Some(_) => {}
            }
        }
        match serde_json::from_value(value).map_err(serde::de::Error::custom)? {
            Tagged::Saro(c) => Ok(ModelConfig::Saro(c)),
            Tagged::Deform(c) => Ok(ModelConfig::Deform(c)),
            Tagged::Track(c) => Ok(ModelConfig::Track(c)),
        }
    }
}

impl Serialize for ModelConfig {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        #[derive(Serialize)]
        #[serde(tag = "kind", rename_all = "lowercase")]
        enum Tagged<'a> {
            Saro(&'a SaroConfig),
            Deform(&'a DeformConfig),
            Track(&'a TrackConfig),
        }
        match self {
            ModelConfig::Saro(c) => Tagged::Saro(c).serialize(s),
            ModelConfig::Deform(c) => Tagged::Deform(c).serialize(s),
            ModelConfig::Track(c) => Tagged::Track(c).serialize(s),
            ModelConfig::Custom { kind, options } => {
                let mut map = serde_json::Map::new();
                map.insert("kind".into(), kind.clone().into());
                map.extend(options.clone());
                map.serialize(s)
            }
        }
    }
}

/// An iteration count scaled by `s` (a budget's schedule): `round(n s)`, at least 1.
pub fn scaled_count(n: usize, s: f64) -> usize {
    ((n as f64) * s).round().max(1.0) as usize
}

impl ModelConfig {
    /// The built-in kinds.
    pub const KINDS: [&'static str; 3] = ["saro", "deform", "track"];

    /// SH degree of a custom representation whose options give no `sh_degree`.
    pub const CUSTOM_SH_DEGREE: usize = 3;

    /// The kind's name (`"saro"`, or a custom representation's), as the built
    /// representation's `name()`.
    pub fn kind(&self) -> &str {
        match self {
            ModelConfig::Saro(_) => "saro",
            ModelConfig::Deform(_) => "deform",
            ModelConfig::Track(_) => "track",
            ModelConfig::Custom { kind, .. } => kind,
        }
    }

    /// The default config of the kind called `name`: a built-in's defaults, or a
    /// custom representation with no options (its factory's defaults). Refuses a
    /// name that is not 1 to 64 letters, digits or `_`.
    pub fn default_of(name: &str) -> Result<Self, String> {
        match name {
            "saro" => Ok(ModelConfig::Saro(SaroConfig::default())),
            "deform" => Ok(ModelConfig::Deform(DeformConfig::default())),
            "track" => Ok(ModelConfig::Track(TrackConfig::default())),
            other => {
                let custom = ModelConfig::Custom {
                    kind: other.to_string(),
                    options: serde_json::Map::new(),
                };
                custom.validate().map(|()| custom)
            }
        }
    }

    /// A custom representation's options (the `model` section without `kind`), for
    /// its factory to deserialize and validate; `None` for a built-in kind.
    pub fn options(&self) -> Option<&serde_json::Map<String, serde_json::Value>> {
        match self {
            ModelConfig::Custom { options, .. } => Some(options),
            _ => None,
        }
    }

    /// Checks every value, naming the field (a custom representation: its name;
    /// its factory checks its options).
    pub fn validate(&self) -> Result<(), String> {
        match self {
            ModelConfig::Saro(c) => c.validate(),
            ModelConfig::Deform(c) => c.validate(),
            ModelConfig::Track(c) => c.validate(),
            ModelConfig::Custom { kind, .. } => {
                if maaf_io::is_plugin_name(kind) {
                    Ok(())
                } else {
                    Err(format!(
                        "model.kind: `{kind}` is not a representation name (1 to 64 letters, digits or _)"
                    ))
                }
            }
        }
    }

    /// Highest SH degree the model stores (the renderer's degree grows up to it): a
    /// custom representation's `sh_degree` option, else [`Self::CUSTOM_SH_DEGREE`].
    pub fn sh_degree(&self) -> usize {
        match self {
            ModelConfig::Saro(c) => c.sh_degree,
            ModelConfig::Deform(c) => c.sh_degree,
            ModelConfig::Track(c) => c.sh_degree,
            ModelConfig::Custom { options, .. } => options
                .get("sh_degree")
                .and_then(serde_json::Value::as_u64)
                .map_or(Self::CUSTOM_SH_DEGREE, |d| d as usize),
        }
    }

    /// Iterations rendered as plain 3D Gaussians before the dynamic stage, mutably:
    /// SaRO's `static_iterations`, deform's `warm_up` (demos and tests shorten it);
    /// `None` for the tracking model (its first frame is a share of the run) and a
    /// custom representation.
    pub fn warm_up_mut(&mut self) -> Option<&mut usize> {
        match self {
            ModelConfig::Saro(c) => Some(&mut c.static_iterations),
            ModelConfig::Deform(c) => Some(&mut c.warm_up),
            ModelConfig::Track(_) | ModelConfig::Custom { .. } => None,
        }
    }

    /// Scales the representation's own iteration counts by `s` (a budget's shorter or
    /// longer schedule, `maaf train --budget`): SaRO's static stage, adaptive period and
    /// learning-rate decays; Deformable-3DGS's warm-up, decays and GroupFlow's
    /// iteration. The tracking model's schedule is a share of the run already; a
    /// registered representation's options are its own and are left as they are.
    pub fn scale_schedule(&mut self, s: f64) {
        let scaled = |n: &mut usize| *n = scaled_count(*n, s);
        match self {
            ModelConfig::Saro(c) => {
                scaled(&mut c.static_iterations);
                scaled(&mut c.lr.max_steps);
                if c.adaptive_every > 0 {
                    scaled(&mut c.adaptive_every);
                }
            }
            ModelConfig::Deform(c) => {
                scaled(&mut c.warm_up);
                scaled(&mut c.lr.position_max_steps);
                scaled(&mut c.lr.deform_max_steps);
                scaled(&mut c.group_flow.at);
            }
            ModelConfig::Track(_) | ModelConfig::Custom { .. } => {}
        }
    }

    /// Fills in what the data decides unless the config set it: SaRO's `duration`
    /// (the number of distinct training times). Called once when a run starts, so
    /// `config.json` records the value used.
    pub fn resolve(&mut self, init: &ModelInit) {
        match self {
            ModelConfig::Saro(c) => {
                c.duration.get_or_insert(init.frames() as f64);
            }
            ModelConfig::Deform(_) | ModelConfig::Track(_) | ModelConfig::Custom { .. } => {}
        }
    }
}

/// What a representation is built from besides its config.
#[derive(Clone, Debug)]
pub struct ModelInit {
    /// Initial points and colours (seeded, inside the scene bounds).
    pub cloud: PointCloud,
    /// Scene extent (3DGS `spatial_lr_scale`: scales the position learning rate).
    pub extent: f64,
    /// Seed of every random initialisation.
    pub seed: u64,
    /// The distinct training times, ascending (the frames of the sequence).
    pub times: Vec<f64>,
    /// Iterations of the run (a model whose stages are shares of the run reads it:
    /// the tracking model's frames).
    pub iterations: usize,
}

impl ModelInit {
    /// Number of distinct training times (frames of the sequence).
    pub fn frames(&self) -> usize {
        self.times.len()
    }
}

/// Builds the built-in representation `config` describes (config already resolved);
/// a custom kind is an error naming it (its program's factory builds it).
pub fn build_model(
    config: &ModelConfig,
    init: &ModelInit,
) -> Result<Box<dyn Representation<f32>>, String> {
    match config {
        ModelConfig::Saro(c) => Ok(Box::new(SaroModel::<f32>::from_point_cloud(
            &init.cloud,
            c.clone(),
            init.extent,
            init.seed,
        ))),
        ModelConfig::Deform(c) => {
            let mut m = DeformModel::<f32>::from_point_cloud(&init.cloud, c.clone(), init.seed);
            m.set_frames(init.frames());
            Ok(Box::new(m))
        }
        ModelConfig::Track(c) => Ok(Box::new(TrackModel::<f32>::new(c.clone(), init)?)),
        ModelConfig::Custom { kind, .. } => Err(format!(
            "model.kind `{kind}` is not a built-in representation ({})",
            ModelConfig::KINDS.join(", ")
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kind_is_recorded_and_an_untagged_config_reads_as_saro() {
        let json = serde_json::to_value(ModelConfig::default()).expect("json");
        assert_eq!(json["kind"], "saro");
        let old: ModelConfig = serde_json::from_str(r#"{"hidden": 32}"#).expect("untagged");
        let ModelConfig::Saro(c) = &old else {
            panic!("saro")
        };
        assert_eq!(c.hidden, 32);
        assert!(ModelConfig::default_of("ne rf").is_err());
        let d: ModelConfig =
            serde_json::from_str(r#"{"kind": "deform", "width": 32}"#).expect("deform");
        assert!(matches!(&d, ModelConfig::Deform(c) if c.width == 32 && c.depth == 4));
    }

    #[test]
    fn another_kind_keeps_its_options_as_json_and_writes_them_back() {
        let text = r#"{"kind": "nerf", "width": 8, "note": "x"}"#;
        let c: ModelConfig = serde_json::from_str(text).expect("custom");
        assert_eq!(c.kind(), "nerf");
        let options = c.options().expect("options");
        assert_eq!(
            (options.len(), &options["width"]),
            (2, &serde_json::json!(8))
        );
        assert!(!options.contains_key("kind"));
        let back: serde_json::Value = serde_json::to_value(&c).expect("json");
        let want: serde_json::Value = serde_json::from_str(text).expect("json");
        assert_eq!(back, want);
        assert_eq!(c.sh_degree(), ModelConfig::CUSTOM_SH_DEGREE);
        assert!(build_model(&c, &init()).is_err());
        let bad: ModelConfig = serde_json::from_str(r#"{"kind": "a b"}"#).expect("parses");
        assert!(bad.validate().expect_err("bad name").contains("model.kind"));
    }

    fn init() -> ModelInit {
        ModelInit {
            cloud: PointCloud::random_in_box(4, -1.0, 1.0, 0),
            extent: 1.0,
            seed: 0,
            times: (0..5).map(|t| f64::from(t) / 5.0).collect(),
            iterations: 100,
        }
    }

    #[test]
    fn duration_comes_from_the_data_unless_set() {
        let init = ModelInit {
            cloud: PointCloud::random_in_box(4, -1.0, 1.0, 0),
            extent: 1.0,
            seed: 0,
            times: (0..50).map(|t| f64::from(t) / 50.0).collect(),
            iterations: 100,
        };
        let mut c = ModelConfig::default();
        c.resolve(&init);
        let ModelConfig::Saro(s) = &c else {
            panic!("saro")
        };
        assert_eq!(s.duration, Some(50.0));
        let mut set = ModelConfig::Saro(SaroConfig {
            duration: Some(150.0),
            ..SaroConfig::default()
        });
        set.resolve(&init);
        let ModelConfig::Saro(s) = &set else {
            panic!("saro")
        };
        assert_eq!(s.duration, Some(150.0));
    }
}
