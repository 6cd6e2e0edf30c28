//! Element types a checkpoint may store, and their conversion to f32.

/// A stored element type. Everything is converted to f32 on load: the
/// networks compute in f32, and the integer tensors of a state dict
/// (BatchNorm's `num_batches_tracked`) are small counters.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DType {
    F32,
    F64,
    F16,
    BF16,
    I64,
    I32,
}

impl DType {
    pub fn size(self) -> usize {
        match self {
            DType::F32 | DType::I32 => 4,
            DType::F64 | DType::I64 => 8,
            DType::F16 | DType::BF16 => 2,
        }
    }

    pub fn is_float(self) -> bool {
        matches!(self, DType::F32 | DType::F64 | DType::F16 | DType::BF16)
    }

    /// From a PyTorch storage class name (`FloatStorage`, …).
    pub(crate) fn from_torch_storage(name: &str) -> Option<Self> {
        Some(match name {
            "FloatStorage" => DType::F32,
            "DoubleStorage" => DType::F64,
            "HalfStorage" => DType::F16,
            "BFloat16Storage" => DType::BF16,
            "LongStorage" => DType::I64,
            "IntStorage" => DType::I32,
            _ => return None,
        })
    }

    /// From a safetensors dtype name (`F32`, …).
    pub(crate) fn from_safetensors(name: &str) -> Option<Self> {
        Some(match name {
            "F32" => DType::F32,
            "F64" => DType::F64,
            "F16" => DType::F16,
            "BF16" => DType::BF16,
            "I64" => DType::I64,
            "I32" => DType::I32,
            _ => return None,
        })
    }

    /// Decodes one little-endian element (`bytes.len() == self.size()`).
    pub(crate) fn decode(self, b: &[u8]) -> f32 {
        match self {
            DType::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
            DType::F64 => {
                f64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]) as f32
            }
            DType::I32 => i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f32,
            DType::I64 => {
                i64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]) as f32
            }
            DType::BF16 => f32::from_bits((u16::from_le_bytes([b[0], b[1]]) as u32) << 16),
            DType::F16 => f16_to_f32(u16::from_le_bytes([b[0], b[1]])),
        }
    }
}

/// IEEE half → single, exact (including subnormals, ±inf and NaN).
fn f16_to_f32(h: u16) -> f32 {
    let sign = if h & 0x8000 != 0 { -1.0 } else { 1.0 };
    let exp = ((h >> 10) & 0x1f) as i32;
    let frac = (h & 0x3ff) as f32;
    sign * match exp {
        0 => frac * 2f32.powi(-24),
        31 if frac == 0.0 => f32::INFINITY,
        31 => f32::NAN,
        _ => (1.0 + frac / 1024.0) * 2f32.powi(exp - 15),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn half_and_bfloat_decode_known_values() {
        assert_eq!(DType::F16.decode(&0x3c00u16.to_le_bytes()), 1.0);
        assert_eq!(DType::F16.decode(&0xc000u16.to_le_bytes()), -2.0);
        assert_eq!(DType::F16.decode(&0x0001u16.to_le_bytes()), 2f32.powi(-24));
        assert_eq!(DType::F16.decode(&0x7bffu16.to_le_bytes()), 65504.0);
        assert_eq!(DType::BF16.decode(&0x3f80u16.to_le_bytes()), 1.0);
        assert_eq!(DType::I64.decode(&(-3i64).to_le_bytes()), -3.0);
    }
}
