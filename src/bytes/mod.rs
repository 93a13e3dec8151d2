//! Byte decoding every reader shares, below the readers themselves: the
//! byte order of numbers ([`Endian`]), bounded decompression (`inflate`:
//! gzip and zlib streams, LZ4 blocks, `.xz` streams, each to exactly the
//! size a header promises), raw or base64 data read a chunk at a time
//! (`stream`), and telling little-endian numbers in a big-endian format
//! ([`byte_order`]). The volume readers, the mesh readers and the VTK XML
//! layer (`vtk_xml`) import from here; this module imports from none of
//! them.

pub mod byte_order;
pub(crate) mod inflate;
pub(crate) mod stream;

/// The byte order of the multi-byte numbers in a file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Endian {
    Little,
    Big,
}

/// A number read from its bytes in either order ([`Endian::read`]).
pub(crate) trait FromBytes: Sized {
    /// Its size in bytes.
    const SIZE: usize;
    /// The number in the first `SIZE` bytes of `c` (which has at least that many).
    fn from_bytes(c: &[u8], endian: Endian) -> Self;
}

macro_rules! from_bytes {
    ($($t:ty),*) => {$(
        impl FromBytes for $t {
            const SIZE: usize = std::mem::size_of::<$t>();
            #[inline]
            fn from_bytes(c: &[u8], endian: Endian) -> Self {
                let w: [u8; std::mem::size_of::<$t>()] = std::array::from_fn(|i| c[i]);
                match endian {
                    Endian::Little => <$t>::from_le_bytes(w),
                    Endian::Big => <$t>::from_be_bytes(w),
                }
            }
        }
    )*};
}

from_bytes!(i8, u8, i16, u16, i32, u32, i64, u64, f32, f64);

impl Endian {
    /// The `T` at the start of `c`, in this byte order.
    #[inline]
    pub(crate) fn read<T: FromBytes>(self, c: &[u8]) -> T {
        T::from_bytes(c, self)
    }

    /// Every whole `T` of `bytes`, in this byte order.
    pub(crate) fn words<T: FromBytes>(self, bytes: &[u8]) -> Vec<T> {
        bytes.chunks_exact(T::SIZE).map(|c| T::from_bytes(c, self)).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn both_orders() {
        assert_eq!(Endian::Big.words::<i16>(&[1, 2, 3, 4, 5]), vec![0x0102, 0x0304]);
        assert_eq!(Endian::Little.words::<u16>(&[1, 2, 3, 4]), vec![0x0201, 0x0403]);
        assert_eq!(Endian::Big.read::<f64>(&0.1f64.to_be_bytes()), 0.1);
        assert_eq!(Endian::Little.read::<u32>(&[1, 0, 0, 0, 9]), 1);
    }
}
