//! The AlexNet feature extractor LPIPS uses: torchvision's `alexnet().features`, cut
//! after each of its five ReLUs.

use crate::layers::{ConvRelu, FeatureMap, max_pool};

/// Shape of one conv layer.
pub(crate) struct LayerShape {
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
}

/// torchvision AlexNet's five conv layers (Krizhevsky 2014 "one weird trick" variant).
pub(crate) const LAYERS: [LayerShape; 5] = [
    LayerShape {
        k: 11,
        stride: 4,
        pad: 2,
        c_in: 3,
        c_out: 64,
    },
    LayerShape {
        k: 5,
        stride: 1,
        pad: 2,
        c_in: 64,
        c_out: 192,
    },
    LayerShape {
        k: 3,
        stride: 1,
        pad: 1,
        c_in: 192,
        c_out: 384,
    },
    LayerShape {
        k: 3,
        stride: 1,
        pad: 1,
        c_in: 384,
        c_out: 256,
    },
    LayerShape {
        k: 3,
        stride: 1,
        pad: 1,
        c_in: 256,
        c_out: 256,
    },
];

/// The five conv layers with their weights.
pub(crate) struct AlexNet {
    /// `conv0..conv4`, each followed by ReLU.
    pub convs: Vec<ConvRelu>,
}

impl AlexNet {
    /// The five ReLU outputs `relu1..relu5` of an input map (already scaled):
    /// conv0, [pool 3/2] conv1, [pool 3/2] conv2, conv3, conv4. `None` when the input
    /// is too small for a layer.
    pub fn features(&self, x: &FeatureMap) -> Option<Vec<FeatureMap>> {
        let mut out: Vec<FeatureMap> = Vec::with_capacity(5);
        for (i, conv) in self.convs.iter().enumerate() {
            let input = match i {
                0 => conv.forward(x)?,
                1 | 2 => conv.forward(&max_pool(&out[i - 1], 3, 2)?)?,
                _ => conv.forward(&out[i - 1])?,
            };
            out.push(input);
        }
        Some(out)
    }
}
