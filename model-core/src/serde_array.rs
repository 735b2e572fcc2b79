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
