//! The serialized FMU state's layout is pinned to its format version: a change of the
//! fields written (added, removed, reordered, of another kind, or written from another
//! value: each field is named in the layout by the expression it is written from, so two
//! fields of one kind swapped change it too) changes the layout hash, and this test then
//! asks for a new `FORMAT_VERSION`, so that an old buffer is refused by its version rather
//! than misread.

use std::ffi::CString;

use cyclic_mechanism::instance::{Instance, Interface, Version, FORMAT_VERSION};
use cyclic_mechanism::plant::Value;
use cyclic_mechanism::variables::value_reference;
use integrators::bytes::fnv1a_64;

/// The version and the layout it was pinned with.
const PINNED: (u32, u64) = (20, 0x6f5b7d48734ebcb9);

fn instance(interface: Interface) -> Instance {
    let name = CString::new("layout").expect("no NUL");
    let mut fmu = Instance::new(interface, Version::Fmi2, name, None, false);
    fmu.setup_experiment(None, 0.0, None).expect("a start");
    fmu
}

fn started(interface: Interface, slots: &[(&str, i32)]) -> Instance {
    let mut fmu = instance(interface);
    fmu.enter_initialization_mode().expect("initialisation");
    let values = slots
        .iter()
        .map(|&(name, v)| (value_reference(name).expect("a slot"), Value::Integer(v)));
    fmu.set_values(values).expect("the slots");
    fmu.exit_initialization_mode().expect("initialised");
    if interface == Interface::CoSimulation {
        for k in 0..20 {
            let t = f64::from(k) * 0.025;
            fmu.do_step(t, 0.025).expect("a step");
        }
    }
    fmu
}

#[test]
fn the_serialized_layout_is_the_one_its_format_version_was_pinned_with() {
    let states = [
        instance(Interface::CoSimulation),
        started(Interface::CoSimulation, &[]),
        started(
            Interface::CoSimulation,
            &[
                ("sensitivity_1.parameter", 6),
                ("sensitivity_3.parameter", 5),
            ],
        ),
        started(Interface::ModelExchange, &[]),
    ];
    let layouts: Vec<u8> = states
        .iter()
        .flat_map(|s| s.save().layout().to_le_bytes())
        .collect();
    let layout = fnv1a_64(&layouts);
    assert_eq!(
        (FORMAT_VERSION, layout),
        PINNED,
        "the serialized layout is {layout:#x}: when it changed, raise FORMAT_VERSION in \
         src/instance/state_frame.rs and pin the two here"
    );
}
