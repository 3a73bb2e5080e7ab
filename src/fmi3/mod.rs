//! FMI 3.0. So far its model description, generated from the same variable table as FMI
//! 2.0's; the functions of `fmi3Functions.h` are not exported yet, so no FMI 3.0 archive is
//! packed.

pub mod model_description;
