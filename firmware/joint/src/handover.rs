//! A value handed once from `main` to an interrupt handler: `main` puts it before it enables
//! the interrupt, the handler takes it on its first run and keeps it in a handler-local static.
//! Both are short critical sections (a word moved), at boot and at the handler's first run;
//! from then on the handler owns the value and touches no lock.
use core::cell::Cell;
use critical_section::Mutex;

pub struct HandOver<T>(Mutex<Cell<Option<T>>>);

impl<T> HandOver<T> {
    pub const fn new() -> Self {
        HandOver(Mutex::new(Cell::new(None)))
    }

    /// Hands `value` over (replacing one not yet taken).
    pub fn put(&self, value: T) {
        critical_section::with(|cs| self.0.borrow(cs).set(Some(value)));
    }

    /// The value, once.
    pub fn take(&self) -> Option<T> {
        critical_section::with(|cs| self.0.borrow(cs).take())
    }
}

impl<T> Default for HandOver<T> {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_value_is_taken_once() {
        static SLOT: HandOver<u32> = HandOver::new();
        assert_eq!(SLOT.take(), None);
        SLOT.put(7);
        assert_eq!(SLOT.take(), Some(7));
        assert_eq!(SLOT.take(), None);
    }
}
