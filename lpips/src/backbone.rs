//! The two backbones LPIPS v0.1 offers, as stage lists: torchvision's `alexnet().features`
//! cut after each of its five ReLUs, and `vgg16().features` cut at relu1_2, relu2_2,
//! relu3_3, relu4_3 and relu5_3 (the original package's `pn.alexnet` / `pn.vgg16`).

use std::path::PathBuf;
use std::str::FromStr;

use crate::layers::{ConvRelu, FeatureMap, max_pool};

/// Which feature network LPIPS compares images in: the `net=` of the original package
/// (`lpips.LPIPS(net='alex')` / `net='vgg'`), each with its own v0.1 linear layers.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Net {
    /// AlexNet (the package's default; committed weights, about 1/6 of VGG's cost).
    #[default]
    Alex,
    /// VGG16 (what 3DGS-family evaluation scripts, the MAAF release's among them, call;
    /// weights fetched by `lpips/tools/fetch_vgg_weights.sh`).
    Vgg,
}

impl Net {
    /// The package's name for it: `alex` or `vgg`.
    pub fn name(self) -> &'static str {
        match self {
            Net::Alex => "alex",
            Net::Vgg => "vgg",
        }
    }

    /// The network's usual name, for tables and messages: `AlexNet` or `VGG16`.
    pub fn label(self) -> &'static str {
        match self {
            Net::Alex => "AlexNet",
            Net::Vgg => "VGG16",
        }
    }

    /// How a missing weights file is made: converted once (AlexNet's is committed) or
    /// fetched (VGG16's).
    pub(crate) fn weights_source(self) -> &'static str {
        match self {
            Net::Alex => "lpips/tools/convert_weights.py",
            Net::Vgg => "bash lpips/tools/fetch_vgg_weights.sh",
        }
    }

    /// Smallest height and width the network accepts. AlexNet: its second max-pool
    /// needs a 3 x 3 input, which takes a conv0 output of 7, i.e.
    /// `(31 + 4 - 11) / 4 + 1 = 7`. VGG16: four 2 x 2 pools halve (rounding down) to
    /// at least one pixel, `floor(16 / 2^4) = 1`.
    pub fn min_size(self) -> usize {
        match self {
            Net::Alex => 31,
            Net::Vgg => 16,
        }
    }

    /// The environment variable overriding [`Net::default_weights_path`]:
    /// `MAAF_LPIPS_WEIGHTS` (AlexNet) or `MAAF_LPIPS_VGG_WEIGHTS`.
    pub fn weights_env(self) -> &'static str {
        match self {
            Net::Alex => "MAAF_LPIPS_WEIGHTS",
            Net::Vgg => "MAAF_LPIPS_VGG_WEIGHTS",
        }
    }

    /// Where [`crate::Lpips::load_default`] reads this network's weights: the
    /// environment variable [`Net::weights_env`] when set and non-empty, else
    /// `lpips/weights/{alex,vgg}_v0.1.safetensors` in the source tree (AlexNet's is
    /// committed; VGG's, 59 MB, is written by `lpips/tools/fetch_vgg_weights.sh`).
    pub fn default_weights_path(self) -> PathBuf {
        match std::env::var_os(self.weights_env()) {
            Some(p) if !p.is_empty() => PathBuf::from(p),
            _ => PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/weights"))
                .join(format!("{}_v0.1.safetensors", self.name())),
        }
    }

    /// The network's stages in order.
    pub(crate) fn stages(self) -> &'static [Stage] {
        match self {
            Net::Alex => &ALEX,
            Net::Vgg => &VGG16,
        }
    }
}

impl std::fmt::Display for Net {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Net {
    type Err = String;

    /// `alex` / `alexnet` or `vgg` / `vgg16`.
    fn from_str(s: &str) -> Result<Net, String> {
        match s {
            "alex" | "alexnet" => Ok(Net::Alex),
            "vgg" | "vgg16" => Ok(Net::Vgg),
            _ => Err(format!("unknown LPIPS network `{s}` (alex or vgg)")),
        }
    }
}

/// One conv layer with ReLU, optionally preceded by a max-pool, optionally tapped
/// (its output is one of LPIPS's five feature maps).
pub(crate) struct Stage {
    /// `(window, stride)` of a "valid" max-pool applied to the input first.
    pub pool: Option<(usize, usize)>,
    /// Kernel size.
    pub k: usize,
    /// Stride.
    pub stride: usize,
    /// Zero padding.
    pub pad: usize,
    /// Input channels.
    pub c_in: usize,
    /// Output channels.
    pub c_out: usize,
    /// Whether the ReLU output is an LPIPS feature map.
    pub tap: bool,
}

/// An AlexNet conv (every one tapped), with the pool before it if any.
const fn alex(
    pool: Option<(usize, usize)>,
    k: usize,
    stride: usize,
    pad: usize,
    io: (usize, usize),
) -> Stage {
    Stage {
        pool,
        k,
        stride,
        pad,
        c_in: io.0,
        c_out: io.1,
        tap: true,
    }
}

/// A 3 x 3 pad-1 VGG conv, `pool`: 2 x 2 stride-2 pool before, `tap`: feature output.
const fn vgg(pool: bool, c_in: usize, c_out: usize, tap: bool) -> Stage {
    Stage {
        pool: if pool { Some((2, 2)) } else { None },
        k: 3,
        stride: 1,
        pad: 1,
        c_in,
        c_out,
        tap,
    }
}

/// torchvision AlexNet (Krizhevsky 2014 "one weird trick" variant): 11x11/4 pad 2 -> 64,
/// pool 3/2, 5x5 pad 2 -> 192, pool 3/2, 3x3 pad 1 -> 384, 256, 256; every ReLU tapped.
const ALEX: [Stage; 5] = [
    alex(None, 11, 4, 2, (3, 64)),
    alex(Some((3, 2)), 5, 1, 2, (64, 192)),
    alex(Some((3, 2)), 3, 1, 1, (192, 384)),
    alex(None, 3, 1, 1, (384, 256)),
    alex(None, 3, 1, 1, (256, 256)),
];

/// torchvision VGG16 (configuration D) up to relu5_3: blocks of 2, 2, 3, 3, 3 convs of
/// 64, 128, 256, 512, 512 channels, a 2x2/2 pool between blocks, the last ReLU of each
/// block tapped.
const VGG16: [Stage; 13] = [
    vgg(false, 3, 64, false),
    vgg(false, 64, 64, true),
    vgg(true, 64, 128, false),
    vgg(false, 128, 128, true),
    vgg(true, 128, 256, false),
    vgg(false, 256, 256, false),
    vgg(false, 256, 256, true),
    vgg(true, 256, 512, false),
    vgg(false, 512, 512, false),
    vgg(false, 512, 512, true),
    vgg(true, 512, 512, false),
    vgg(false, 512, 512, false),
    vgg(false, 512, 512, true),
];

/// A backbone with its weights: one [`ConvRelu`] per stage of [`Net::stages`].
pub(crate) struct Backbone {
    /// Which network.
    pub net: Net,
    /// One conv per stage, in order.
    pub convs: Vec<ConvRelu>,
}

impl Backbone {
    /// The five tapped ReLU outputs of an input map (already scaled), running the stages
    /// in order (pool, conv, ReLU). `None` when the input is too small for a layer.
    pub fn features(&self, x: &FeatureMap) -> Option<Vec<FeatureMap>> {
        let mut taps: Vec<FeatureMap> = Vec::with_capacity(5);
        // The newest output when it was not tapped (a tapped one is `taps.last()`).
        let mut untapped: Option<FeatureMap> = None;
        for (stage, conv) in self.net.stages().iter().zip(&self.convs) {
            let input = untapped.as_ref().or(taps.last()).unwrap_or(x);
            let y = match stage.pool {
                Some((k, s)) => conv.forward(&max_pool(input, k, s)?)?,
                None => conv.forward(input)?,
            };
            if stage.tap {
                taps.push(y);
                untapped = None;
            } else {
                untapped = Some(y);
            }
        }
        Some(taps)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn both_networks_tap_five_maps_with_channels_that_chain() {
        for net in [Net::Alex, Net::Vgg] {
            let stages = net.stages();
            assert_eq!(stages.iter().filter(|s| s.tap).count(), 5, "{net}");
            assert_eq!(stages[0].c_in, 3);
            for w in stages.windows(2) {
                assert_eq!(w[0].c_out, w[1].c_in, "{net}");
            }
        }
        let taps = |net: Net| -> Vec<usize> {
            net.stages()
                .iter()
                .filter(|s| s.tap)
                .map(|s| s.c_out)
                .collect()
        };
        assert_eq!(taps(Net::Alex), [64, 192, 384, 256, 256]);
        assert_eq!(taps(Net::Vgg), [64, 128, 256, 512, 512]);
    }

    /// The network with constant weights (every output positive, so nothing vanishes).
    fn constant_backbone(net: Net) -> Backbone {
        let convs = net
            .stages()
            .iter()
            .map(|s| ConvRelu {
                k: s.k,
                stride: s.stride,
                pad: s.pad,
                c_in: s.c_in,
                c_out: s.c_out,
                weight: vec![0.01; s.k * s.k * s.c_in * s.c_out],
                bias: vec![0.1; s.c_out],
            })
            .collect();
        Backbone { net, convs }
    }

    #[test]
    fn min_size_is_the_smallest_input_every_layer_fits() {
        for net in [Net::Alex, Net::Vgg] {
            let backbone = constant_backbone(net);
            let input = |n: usize| FeatureMap {
                h: n,
                w: n + 3,
                c: 3,
                data: vec![0.5; n * (n + 3) * 3],
            };
            let n = net.min_size();
            let taps = backbone.features(&input(n)).expect("min_size fits");
            let shapes: Vec<(usize, usize)> = taps.iter().map(|f| (f.h, f.c)).collect();
            eprintln!("{net} at {n}: (rows, channels) of the taps {shapes:?}");
            assert_eq!(taps.len(), 5);
            assert!(
                taps.iter()
                    .all(|f| f.h >= 1 && f.data.iter().all(|&v| v > 0.0))
            );
            assert!(
                backbone.features(&input(n - 1)).is_none(),
                "{net} at {}",
                n - 1
            );
        }
        // VGG16's taps halve from full size: 16, 8, 4, 2, 1 rows.
        let taps = constant_backbone(Net::Vgg)
            .features(&FeatureMap {
                h: 16,
                w: 16,
                c: 3,
                data: vec![0.5; 16 * 16 * 3],
            })
            .expect("fits");
        let rows: Vec<usize> = taps.iter().map(|f| f.h).collect();
        assert_eq!(rows, [16, 8, 4, 2, 1]);
    }

    #[test]
    fn names_parse_back_and_unknown_ones_are_named_in_the_error() {
        for net in [Net::Alex, Net::Vgg] {
            assert_eq!(net.name().parse::<Net>(), Ok(net));
        }
        assert_eq!("vgg16".parse::<Net>(), Ok(Net::Vgg));
        let err = "squeeze".parse::<Net>().expect_err("not offered");
        assert!(err.contains("squeeze"), "{err}");
    }
}
