//! Every output at every communication point of fixed scenarios, through the exported C
//! functions, against `tests/golden/outputs.txt`: a refactoring of the inside must not move
//! one bit. The file holds, per scenario, a hash of the bits of every point in windows of
//! 100 points (so a difference is found to within a second of simulated time) and the values
//! themselves at every whole second (so that the first difference can be read). Runs that go
//! through Radau IIA keep their values at every tenth of a second, and are judged against
//! the tolerance instead: a change of its linear algebra may move their last bits.
//!
//! `GOLDEN_WRITE=1 cargo test --test golden_outputs` rewrites the file from the code as it
//! is; it is written once, before a change, by the code the change must not alter.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use cyclic_mechanism::fmi2::*;
use cyclic_mechanism::variables::{variables, Causality, VarType};
use fmi_sys::fmi2::*;
use integrators::bytes::fnv1a_64;

mod common;

const GOLDEN: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/golden/outputs.txt");
const OK: fmi2Status = fmi2Status_fmi2OK;
const WINDOW: usize = 100;

/// How a scenario is judged.
#[derive(Clone, Copy, PartialEq)]
enum Judged {
    /// Every bit of every output at every point.
    Bits,
    /// Reals within `tolerance` × this factor of the golden values (relative and absolute).
    Tolerance(f64),
}

struct Scenario {
    name: &'static str,
    parameters: Vec<(&'static str, f64)>,
    integers: Vec<(&'static str, i32)>,
    builtin_laws: bool,
    tolerance: f64,
    step: f64,
    stop: f64,
    judged: Judged,
}

fn paper(k34: f64) -> Vec<(&'static str, f64)> {
    common::paper_laws()
        .into_iter()
        .chain([("k34", k34)])
        .collect()
}

fn scenarios() -> Vec<Scenario> {
    let cs = |name, parameters: Vec<(&'static str, f64)>| Scenario {
        name,
        parameters,
        integers: vec![],
        builtin_laws: true,
        tolerance: 1e-8,
        step: 0.01,
        stop: 10.0,
        judged: Judged::Bits,
    };
    let with_laws = |geometry: &[(&'static str, f64)]| {
        let mut p = paper(100.0);
        p.extend_from_slice(geometry);
        p
    };
    let mut free = cs(
        "free_run",
        vec![("omega1_0", 6.0), ("twist12_0", 0.3), ("twist34_0", -0.1)],
    );
    free.builtin_laws = false;
    free.tolerance = 1e-10;
    let mut fine = cs("case_1_fine_steps", paper(100.0));
    fine.step = 1e-3;
    fine.stop = 2.0;
    let mut radau = cs("case_1_radau", paper(100.0));
    radau.integers = vec![("solver", 3)];
    radau.step = 0.1;
    radau.judged = Judged::Tolerance(20.0);
    let mut stiff = cs(
        "stiff_springs_auto",
        vec![("k12", 1e6), ("d12", 50.0), ("k34", 1e6), ("d34", 50.0)],
    );
    stiff.tolerance = 1e-6;
    stiff.step = 0.1;
    stiff.stop = 2.0;
    stiff.judged = Judged::Tolerance(20.0);
    vec![
        cs("case_1", paper(100.0)),
        cs("case_2", paper(40.0)),
        fine,
        free,
        cs(
            "non_grashof",
            with_laws(&[("L", 0.96), ("phi2_0", std::f64::consts::PI)]),
        ),
        cs(
            "double_crank",
            with_laws(&[("l", 0.1), ("l2", 0.4), ("l3", 0.45), ("L", 0.5)]),
        ),
        cs(
            "double_rocker",
            with_laws(&[
                ("l", 0.5),
                ("l2", 0.4),
                ("l3", 0.45),
                ("L", 0.15),
                ("phi2_0", 1.0),
            ]),
        ),
        cs(
            "non_grashof_2",
            with_laws(&[
                ("l", 0.4),
                ("l2", 0.3),
                ("l3", 0.35),
                ("L", 0.5),
                ("phi2_0", 1.0),
            ]),
        ),
        radau,
        stiff,
    ]
}

/// The outputs, by type, in value-reference order.
struct Outputs {
    reals: (Vec<u32>, Vec<&'static str>),
    integers: (Vec<u32>, Vec<&'static str>),
}

fn outputs() -> Outputs {
    let mut o = Outputs {
        reals: (vec![], vec![]),
        integers: (vec![], vec![]),
    };
    for (vr, v) in variables().filter(|(_, v)| v.causality() == Causality::Output) {
        let list = match v.var_type() {
            VarType::Real => &mut o.reals,
            _ => &mut o.integers,
        };
        list.0.push(vr);
        list.1.push(v.name);
    }
    o
}

/// One point: the Reals' bits, then the Integers and Enumerations.
type Point = (Vec<f64>, Vec<i32>);

fn run(s: &Scenario, o: &Outputs) -> Vec<Point> {
    use cyclic_mechanism::variables::value_reference;
    let c = common::instantiate(c"golden");
    let vr = |name: &str| value_reference(name).expect("a known name");
    let read = |c| -> Point {
        let mut reals = vec![0.0; o.reals.0.len()];
        let mut integers = vec![0; o.integers.0.len()];
        // SAFETY: a live instance; each array holds as many elements as its references.
        unsafe {
            assert_eq!(
                fmi2GetReal(c, o.reals.0.as_ptr(), reals.len(), reals.as_mut_ptr()),
                OK
            );
            assert_eq!(
                fmi2GetInteger(
                    c,
                    o.integers.0.as_ptr(),
                    integers.len(),
                    integers.as_mut_ptr()
                ),
                OK
            );
        }
        (reals, integers)
    };
    let points = (s.stop / s.step).round() as usize;
    let mut recorded = Vec::with_capacity(points + 1);
    // SAFETY: a live instance; every array holds the count passed with it.
    unsafe {
        assert_eq!(fmi2SetupExperiment(c, 1, s.tolerance, 0.0, 1, s.stop), OK);
        assert_eq!(fmi2EnterInitializationMode(c), OK);
        let laws = [vr("builtin_laws")];
        let on = [s.builtin_laws as fmi2Boolean];
        assert_eq!(fmi2SetBoolean(c, laws.as_ptr(), 1, on.as_ptr()), OK);
        for (name, value) in &s.parameters {
            assert_eq!(fmi2SetReal(c, &vr(name), 1, value), OK, "{name}");
        }
        for (name, value) in &s.integers {
            assert_eq!(fmi2SetInteger(c, &vr(name), 1, value), OK, "{name}");
        }
        assert_eq!(fmi2ExitInitializationMode(c), OK);
        recorded.push(read(c));
        let mut t = 0.0;
        for k in 1..=points {
            let next = k as f64 * s.step;
            assert_eq!(fmi2DoStep(c, t, next - t, 1), OK, "{} at {t}", s.name);
            t = next;
            recorded.push(read(c));
        }
        fmi2FreeInstance(c);
    }
    recorded
}

fn point_bytes(p: &Point) -> Vec<u8> {
    p.0.iter()
        .flat_map(|x| x.to_bits().to_le_bytes())
        .chain(p.1.iter().flat_map(|i| i.to_le_bytes()))
        .collect()
}

/// The file's lines for one scenario.
fn describe(s: &Scenario, o: &Outputs, points: &[Point]) -> String {
    let mut text = format!("scenario {}\n", s.name);
    if s.judged == Judged::Bits {
        for (w, window) in points.chunks(WINDOW).enumerate() {
            let bytes: Vec<u8> = window.iter().flat_map(point_bytes).collect();
            writeln!(text, "window {w} {:016x}", fnv1a_64(&bytes)).unwrap();
        }
    }
    let every = match s.judged {
        Judged::Bits => (1.0 / s.step).round() as usize,
        Judged::Tolerance(_) => 1,
    };
    for (k, p) in points.iter().enumerate().step_by(every) {
        write!(text, "point {k}").unwrap();
        for (name, x) in o.reals.1.iter().zip(&p.0) {
            write!(text, " {name}={:016x}", x.to_bits()).unwrap();
        }
        for (name, i) in o.integers.1.iter().zip(&p.1) {
            write!(text, " {name}={i}").unwrap();
        }
        text.push('\n');
    }
    text
}

/// The golden file's lines, by scenario.
fn golden() -> BTreeMap<String, Vec<String>> {
    let text = std::fs::read_to_string(GOLDEN).expect("tests/golden/outputs.txt");
    let mut by_scenario = BTreeMap::new();
    let mut current: Option<String> = None;
    for line in text.lines() {
        if let Some(name) = line.strip_prefix("scenario ") {
            current = Some(name.to_string());
            by_scenario.insert(name.to_string(), vec![]);
        } else if let Some(name) = &current {
            by_scenario.get_mut(name).unwrap().push(line.to_string());
        }
    }
    by_scenario
}

fn values_of(line: &str) -> BTreeMap<&str, f64> {
    line.split(' ')
        .skip(2)
        .filter_map(|field| field.split_once('='))
        .filter(|(_, hex)| hex.len() == 16)
        .map(|(name, hex)| (name, f64::from_bits(u64::from_str_radix(hex, 16).unwrap())))
        .collect()
}

fn compare(s: &Scenario, expected: &[String], actual: &str) {
    let actual: Vec<&str> = actual.lines().skip(1).collect();
    assert_eq!(expected.len(), actual.len(), "{}: lines", s.name);
    for (e, a) in expected.iter().zip(&actual) {
        match s.judged {
            Judged::Bits => {
                if e.starts_with("window") && e != a {
                    let w: usize = e.split(' ').nth(1).unwrap().parse().unwrap();
                    let point = |l: &&String| l.starts_with(&format!("point {}", w * WINDOW));
                    let first = expected.iter().find(point);
                    panic!(
                        "{}: the outputs differ in points {}..{} (at {} s steps of {})\n\
                         golden at the window's start: {first:?}",
                        s.name,
                        w * WINDOW,
                        (w + 1) * WINDOW,
                        s.step * (w * WINDOW) as f64,
                        s.step
                    );
                }
                assert_eq!(e, a, "{}", s.name);
            }
            Judged::Tolerance(factor) => {
                let bound = factor * s.tolerance;
                let (ev, av) = (values_of(e), values_of(a));
                for (name, x) in &ev {
                    let y = av[name];
                    let error = (x - y).abs() / (1.0 + x.abs());
                    assert!(
                        error <= bound,
                        "{} {}: {name} = {y} against golden {x}, error {error:e} > {bound:e}",
                        s.name,
                        e.split(' ').take(2).collect::<Vec<_>>().join(" ")
                    );
                }
            }
        }
    }
}

/// Model Exchange driven by a fixed master: forward Euler of 1 ms from the case-1 set-up,
/// the chart change handled in event mode whenever the FMU asks; each point holds the
/// outputs, then the states, derivatives and event indicator.
fn run_exchange(o: &Outputs) -> Vec<Point> {
    const N: usize = 6;
    let c = common::instantiate_as(c"golden", fmi2Type_fmi2ModelExchange);
    common::initialise(c, 1e-8, None, &paper(100.0));
    let mut points = vec![];
    let (mut x, mut dx, mut z) = ([0.0; N], [0.0; N], [0.0; 1]);
    let h = 1e-3;
    // SAFETY: a live instance; every array holds the count passed with it.
    unsafe {
        let mut info: fmi2EventInfo = std::mem::zeroed();
        assert_eq!(fmi2NewDiscreteStates(c, &mut info), OK);
        assert_eq!(fmi2EnterContinuousTimeMode(c), OK);
        for k in 0..=3000 {
            assert_eq!(fmi2GetContinuousStates(c, x.as_mut_ptr(), N), OK);
            assert_eq!(fmi2GetDerivatives(c, dx.as_mut_ptr(), N), OK);
            assert_eq!(fmi2GetEventIndicators(c, z.as_mut_ptr(), 1), OK);
            let mut reals = vec![0.0; o.reals.0.len()];
            let mut integers = vec![0; o.integers.0.len()];
            let refs = &o.reals.0;
            assert_eq!(
                fmi2GetReal(c, refs.as_ptr(), refs.len(), reals.as_mut_ptr()),
                OK
            );
            let refs = &o.integers.0;
            assert_eq!(
                fmi2GetInteger(c, refs.as_ptr(), refs.len(), integers.as_mut_ptr()),
                OK
            );
            reals.extend(x.iter().chain(&dx).chain(&z));
            points.push((reals, integers));
            let next: Vec<f64> = x.iter().zip(&dx).map(|(x, d)| x + h * d).collect();
            assert_eq!(fmi2SetTime(c, (k + 1) as f64 * h), OK);
            assert_eq!(fmi2SetContinuousStates(c, next.as_ptr(), N), OK);
            let (mut event, mut terminate) = (0, 0);
            assert_eq!(
                fmi2CompletedIntegratorStep(c, 1, &mut event, &mut terminate),
                OK
            );
            let mut z_new = [0.0];
            assert_eq!(fmi2GetEventIndicators(c, z_new.as_mut_ptr(), 1), OK);
            if event != 0 || z_new[0].signum() != z[0].signum() {
                assert_eq!(fmi2EnterEventMode(c), OK);
                assert_eq!(fmi2NewDiscreteStates(c, &mut info), OK);
                assert_eq!(fmi2EnterContinuousTimeMode(c), OK);
            }
        }
        fmi2FreeInstance(c);
    }
    points
}

fn exchange_scenario() -> Scenario {
    Scenario {
        name: "model_exchange_euler",
        parameters: paper(100.0),
        integers: vec![],
        builtin_laws: true,
        tolerance: 1e-8,
        step: 1e-3,
        stop: 3.0,
        judged: Judged::Bits,
    }
}

fn exchange_outputs(o: &Outputs) -> Outputs {
    let mut names = o.reals.1.clone();
    names.extend([
        "x0", "x1", "x2", "x3", "x4", "x5", "dx0", "dx1", "dx2", "dx3", "dx4", "dx5", "z0",
    ]);
    Outputs {
        reals: (o.reals.0.clone(), names),
        integers: (o.integers.0.clone(), o.integers.1.clone()),
    }
}

#[test]
fn outputs_match_the_golden_file() {
    let o = outputs();
    let all = scenarios();
    if std::env::var_os("GOLDEN_WRITE").is_some() {
        let mut text: String = all.iter().map(|s| describe(s, &o, &run(s, &o))).collect();
        let me = exchange_scenario();
        text += &describe(&me, &exchange_outputs(&o), &run_exchange(&o));
        std::fs::create_dir_all(std::path::Path::new(GOLDEN).parent().unwrap()).unwrap();
        std::fs::write(GOLDEN, text).unwrap();
        return;
    }
    let golden = golden();
    assert_eq!(
        golden.keys().collect::<Vec<_>>(),
        {
            let mut names: Vec<_> = all.iter().map(|s| s.name.to_string()).collect();
            names.push(exchange_scenario().name.to_string());
            names.sort();
            names
        }
        .iter()
        .collect::<Vec<_>>(),
        "the golden file's scenarios"
    );
    for s in &all {
        compare(s, &golden[s.name], &describe(s, &o, &run(s, &o)));
    }
    let me = exchange_scenario();
    let actual = describe(&me, &exchange_outputs(&o), &run_exchange(&o));
    compare(&me, &golden[me.name], &actual);
}
