//! The FMU states an instance has handed out as pointers: each is a boxed [`FmuState`]
//! whose address is registered, so that a pointer the instance did not issue, or freed
//! already, is refused instead of dereferenced.

use super::fmu_state::FmuState;
use super::status::{Failure, Outcome};

#[derive(Default)]
pub(super) struct StateHandles {
    addresses: Vec<usize>,
}

impl StateHandles {
    /// Hand out `saved` as a new pointer.
    pub(super) fn issue(&mut self, saved: FmuState) -> *mut FmuState {
        let pointer = Box::into_raw(Box::new(saved));
        self.addresses.push(pointer as usize);
        pointer
    }

    /// The state behind `pointer`, if issued here and not freed.
    pub(super) fn get(&mut self, pointer: *mut std::ffi::c_void) -> Result<&mut FmuState, Failure> {
        if pointer.is_null() {
            return Err(Failure::error("the FMU state is NULL"));
        }
        if !self.addresses.contains(&(pointer as usize)) {
            return Err(Failure::error(
                "the FMU state was not created by this instance, or was freed already",
            ));
        }
        // SAFETY: the pointer came from Box::into_raw in `issue` and is still owned here
        // (it is registered).
        Ok(unsafe { &mut *pointer.cast::<FmuState>() })
    }

    /// Free a state issued here.
    pub(super) fn free(&mut self, pointer: *mut std::ffi::c_void) -> Outcome {
        self.get(pointer)?;
        self.addresses.retain(|p| *p != pointer as usize);
        // SAFETY: issued by `issue` (checked above) and now removed from the registry.
        drop(unsafe { Box::from_raw(pointer.cast::<FmuState>()) });
        Ok(())
    }
}

impl Drop for StateHandles {
    /// States the master did not free go with their instance.
    fn drop(&mut self) {
        for pointer in self.addresses.drain(..) {
            // SAFETY: every registered address came from Box::into_raw and is freed once.
            drop(unsafe { Box::from_raw(pointer as *mut FmuState) });
        }
    }
}
