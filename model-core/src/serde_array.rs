//! serde for `[T; N]` of a const-generic N (serde itself implements only N ≤ 32, one impl per
//! length): a tuple of N elements, as serde writes its own arrays — a JSON list, and on the wire
//! N elements with no length prefix.
use core::fmt;
use core::marker::PhantomData;
use serde::de::{Error, SeqAccess, Visitor};
use serde::ser::SerializeTuple;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

pub fn serialize<S: Serializer, T: Serialize, const N: usize>(
    array: &[T; N],
    serializer: S,
) -> Result<S::Ok, S::Error> {
    let mut tuple = serializer.serialize_tuple(N)?;
    for element in array {
        tuple.serialize_element(element)?;
    }
    tuple.end()
}

pub fn deserialize<'de, D: Deserializer<'de>, T: Deserialize<'de> + Default, const N: usize>(
    deserializer: D,
) -> Result<[T; N], D::Error> {
    struct Elements<T, const N: usize>(PhantomData<T>);

    impl<'de, T: Deserialize<'de> + Default, const N: usize> Visitor<'de> for Elements<T, N> {
        type Value = [T; N];

        fn expecting(&self, formatter: &mut fmt::Formatter) -> fmt::Result {
            write!(formatter, "a list of {N} numbers")
        }

        fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<[T; N], A::Error> {
            let mut array: [T; N] = core::array::from_fn(|_| T::default());
            for (i, slot) in array.iter_mut().enumerate() {
                *slot = seq.next_element()?.ok_or_else(|| Error::invalid_length(i, &self))?;
            }
            // A longer list (JSON) is refused too, rather than cut.
            let mut extra = 0;
            while seq.next_element::<serde::de::IgnoredAny>()?.is_some() {
                extra += 1;
            }
            if extra > 0 {
                return Err(Error::invalid_length(N + extra, &self));
            }
            Ok(array)
        }
    }

    deserializer.deserialize_tuple(N, Elements::<T, N>(PhantomData))
}

/// serde for the first `count` elements of `([T; N], count)`: a list of at most N elements (an
/// element count beyond N is refused), as serde writes a slice.
pub mod prefix {
    use core::fmt;
    use core::marker::PhantomData;
    use serde::de::{Error, SeqAccess, Visitor};
    use serde::ser::SerializeSeq;
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    pub fn serialize<S: Serializer, T: Serialize, const N: usize>(
        (array, count): &([T; N], u8),
        serializer: S,
    ) -> Result<S::Ok, S::Error> {
        let used =
            array.get(..usize::from(*count)).ok_or_else(|| serde::ser::Error::custom("count beyond the array"))?;
        let mut seq = serializer.serialize_seq(Some(used.len()))?;
        for element in used {
            seq.serialize_element(element)?;
        }
        seq.end()
    }

    pub fn deserialize<'de, D: Deserializer<'de>, T: Deserialize<'de> + Default + Copy, const N: usize>(
        deserializer: D,
    ) -> Result<([T; N], u8), D::Error> {
        struct Prefix<T, const N: usize>(PhantomData<T>);

        impl<'de, T: Deserialize<'de> + Default + Copy, const N: usize> Visitor<'de> for Prefix<T, N> {
            type Value = ([T; N], u8);

            fn expecting(&self, formatter: &mut fmt::Formatter) -> fmt::Result {
                write!(formatter, "a list of at most {N} entries")
            }

            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<([T; N], u8), A::Error> {
                let mut array = [T::default(); N];
                let mut count = 0usize;
                while let Some(element) = seq.next_element()? {
                    let slot = array.get_mut(count).ok_or_else(|| Error::invalid_length(count + 1, &self))?;
                    *slot = element;
                    count += 1;
                }
                Ok((array, u8::try_from(count).map_err(|_| Error::invalid_length(count, &self))?))
            }
        }

        deserializer.deserialize_seq(Prefix::<T, N>(PhantomData))
    }
}
