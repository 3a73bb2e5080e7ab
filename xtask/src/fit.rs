//! `cargo xtask fit SPEC` and `bench-fit`: fit parameters of the packed FMU (or the spec's own)
//! to measured data through `python -m fmusweep fit`, and the fit benchmark.

use crate::cli::{Flag, Parsed};
use crate::setup::Result;
use crate::sweep;

pub(crate) fn job(parsed: &Parsed) -> Result {
    sweep::run_fmusweep(&["fit"], parsed)
}

/// The flags of `cargo xtask fit`, handed on to `python -m fmusweep fit`.
pub(crate) const FLAGS: &[Flag] = &[
    sweep::WORKERS,
    sweep::SCHEDULER,
    Flag {
        name: "out",
        value: Some("DIR"),
        help: "output directory (default: a new results/SPEC-DATE-TIME)",
    },
    Flag {
        name: "resume",
        value: None,
        help: "continue the fit in --out (default: the newest of this spec in results/); the points it evaluated are read, not run",
    },
    sweep::SERIAL,
    Flag {
        name: "no-plots",
        value: None,
        help: "no plots",
    },
];

/// `cargo xtask bench-fit`: the fit benchmark into target/bench-fit.
pub(crate) fn job_bench(parsed: &Parsed) -> Result {
    sweep::run_bench_script("bench/bench_fit.py", "target/bench-fit", parsed)
}

/// `cargo xtask bench-sensitivities`: the FMU's sensitivities in a fit, into
/// target/bench-sensitivities.
pub(crate) fn job_bench_sensitivities(parsed: &Parsed) -> Result {
    sweep::run_bench_script(
        "bench/bench_fit_sensitivities.py",
        "target/bench-sensitivities",
        parsed,
    )
}
