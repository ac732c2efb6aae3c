//! The model kind as data: a tagged config recorded in `config.json` and in every
//! checkpoint, and the one function that builds a representation from it.
//!
//! JSON: `"model": {"kind": "saro", "hidden": 64, ...}`; a config without `kind` is
//! read as `saro` (configs written before the kind existed). A representation the
//! library does not know is trained by handing the trainer a
//! `Box<dyn Representation<f32>>` directly (`Trainer::with_model`).

use serde::{Deserialize, Deserializer, Serialize};

use super::{DeformConfig, DeformModel, PointCloud, Representation, SaroConfig, SaroModel};

/// Which representation to train, with its settings (`--model`).
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum ModelConfig {
    /// SaRO-GS (Sec. 3.2 of the paper): 4D Gaussians plus a scale-aware residual field.
    Saro(SaroConfig),
    /// Deformable 3D Gaussians (Yang et al. 2024): canonical Gaussians plus a
    /// deformation MLP on the encoded centre and time (the paper's plug-in base).
    Deform(DeformConfig),
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
        }
        let mut value = serde_json::Value::deserialize(d)?;
        if let Some(obj) = value.as_object_mut()
            && !obj.contains_key("kind")
        {
            obj.insert("kind".into(), "saro".into());
        }
        match serde_json::from_value(value).map_err(serde::de::Error::custom)? {
            Tagged::Saro(c) => Ok(ModelConfig::Saro(c)),
            Tagged::Deform(c) => Ok(ModelConfig::Deform(c)),
        }
    }
}

impl ModelConfig {
    /// The names `--model` accepts.
    pub const KINDS: [&'static str; 2] = ["saro", "deform"];

    /// The kind's name (`"saro"`), as the built representation's `name()`.
    pub fn kind(&self) -> &'static str {
        match self {
            ModelConfig::Saro(_) => "saro",
            ModelConfig::Deform(_) => "deform",
        }
    }

    /// The default config of the kind called `name`.
    pub fn default_of(name: &str) -> Result<Self, String> {
        match name {
            "saro" => Ok(ModelConfig::Saro(SaroConfig::default())),
            "deform" => Ok(ModelConfig::Deform(DeformConfig::default())),
            other => Err(format!(
                "--model {other}: unknown representation (known: {})",
                Self::KINDS.join(", ")
            )),
        }
    }

    /// Checks every value, naming the field.
    pub fn validate(&self) -> Result<(), String> {
        match self {
            ModelConfig::Saro(c) => c.validate(),
            ModelConfig::Deform(c) => c.validate(),
        }
    }

    /// Highest SH degree the model stores (the renderer's degree grows up to it).
    pub fn sh_degree(&self) -> usize {
        match self {
            ModelConfig::Saro(c) => c.sh_degree,
            ModelConfig::Deform(c) => c.sh_degree,
        }
    }

    /// Iterations rendered as plain 3D Gaussians before the dynamic stage, mutably:
    /// SaRO's `static_iterations`, deform's `warm_up` (demos and tests shorten it).
    pub fn warm_up_mut(&mut self) -> &mut usize {
        match self {
            ModelConfig::Saro(c) => &mut c.static_iterations,
            ModelConfig::Deform(c) => &mut c.warm_up,
        }
    }

    /// Fills in what the data decides unless the config set it: SaRO's `duration`
    /// (the number of distinct training times). Called once when a run starts, so
    /// `config.json` records the value used.
    pub fn resolve(&mut self, init: &ModelInit) {
        match self {
            ModelConfig::Saro(c) => {
                c.duration.get_or_insert(init.frames as f64);
            }
            ModelConfig::Deform(_) => {}
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
    /// Number of distinct training times (frames of the sequence).
    pub frames: usize,
}

/// Builds the representation `config` describes (config already resolved).
pub fn build_model(config: &ModelConfig, init: &ModelInit) -> Box<dyn Representation<f32>> {
    match config {
        ModelConfig::Saro(c) => Box::new(SaroModel::<f32>::from_point_cloud(
            &init.cloud,
            c.clone(),
            init.extent,
            init.seed,
        )),
        ModelConfig::Deform(c) => {
            let mut m = DeformModel::<f32>::from_point_cloud(&init.cloud, c.clone(), init.seed);
            m.set_frames(init.frames);
            Box::new(m)
        }
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
        let bad = serde_json::from_str::<ModelConfig>(r#"{"kind": "nerf"}"#);
        assert!(bad.expect_err("unknown").to_string().contains("nerf"));
        assert!(ModelConfig::default_of("nerf").is_err());
        let d: ModelConfig =
            serde_json::from_str(r#"{"kind": "deform", "width": 32}"#).expect("deform");
        assert!(matches!(&d, ModelConfig::Deform(c) if c.width == 32 && c.depth == 4));
    }

    #[test]
    fn duration_comes_from_the_data_unless_set() {
        let init = ModelInit {
            cloud: PointCloud::random_in_box(4, -1.0, 1.0, 0),
            extent: 1.0,
            seed: 0,
            frames: 50,
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
