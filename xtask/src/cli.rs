//! The jobs' command lines: each job declares its operands and flags once, and from that
//! declaration come the parsing, the refusal of anything undeclared, and `--help`.

use std::collections::BTreeMap;

use crate::setup::Result;

/// A flag: `--name` alone, or `--name VALUE` when `value` names its value.
pub struct Flag {
    pub name: &'static str,
    pub value: Option<&'static str>,
    pub help: &'static str,
}

/// `--quick`: the jobs that offer a small subset of their work.
pub const QUICK: Flag = Flag {
    name: "quick",
    value: None,
    help: "a small subset",
};

/// A job of `cargo xtask`.
pub struct Job {
    pub name: &'static str,
    /// Positional operands, as shown in the usage line (each required).
    pub operands: &'static [&'static str],
    pub about: &'static str,
    pub flags: &'static [Flag],
    pub run: fn(&Parsed) -> Result,
}

/// A parsed command line: the operands in order, and the flags given with their values.
#[derive(Debug, Default)]
pub struct Parsed {
    pub operands: Vec<String>,
    flags: BTreeMap<&'static str, Option<String>>,
}

impl Parsed {
    pub fn has(&self, name: &str) -> bool {
        self.flags.contains_key(name)
    }

    /// The flags given, as they were written (for a job that hands them on).
    pub fn flag_args(&self) -> Vec<String> {
        self.flag_args_except(&[])
    }

    /// The flags given but those named, as they were written.
    pub fn flag_args_except(&self, left_out: &[&str]) -> Vec<String> {
        self.flags
            .iter()
            .filter(|(name, _)| !left_out.contains(name))
            .flat_map(|(name, value)| std::iter::once(format!("--{name}")).chain(value.clone()))
            .collect()
    }
}

/// Parse `args` by `job`'s declaration; `None` when `--help` asked for the job's help
/// (printed here).
pub fn parse(job: &Job, args: &[String]) -> Result<Option<Parsed>> {
    let mut parsed = Parsed::default();
    let mut args = args.iter();
    while let Some(arg) = args.next() {
        if arg == "--help" || arg == "-h" {
            print!("{}", help(job));
            return Ok(None);
        }
        let Some(name) = arg.strip_prefix("--") else {
            parsed.operands.push(arg.clone());
            continue;
        };
        let flag = job
            .flags
            .iter()
            .find(|f| f.name == name)
            .ok_or_else(|| format!("unknown flag {arg}\n\n{}", help(job)))?;
        let value = match flag.value {
            None => None,
            Some(what) => Some(
                args.next()
                    .filter(|v| !v.starts_with("--"))
                    .ok_or_else(|| format!("{arg} needs a value ({what})"))?
                    .clone(),
            ),
        };
        parsed.flags.insert(flag.name, value);
    }
    if parsed.operands.len() != job.operands.len() {
        return Err(format!(
            "expected {} operand(s) ({}), got {:?}\n\n{}",
            job.operands.len(),
            job.operands.join(" "),
            parsed.operands,
            help(job)
        ));
    }
    Ok(Some(parsed))
}

fn usage_line(job: &Job) -> String {
    let mut line = format!("cargo xtask {}", job.name);
    for operand in job.operands {
        line += &format!(" {operand}");
    }
    if !job.flags.is_empty() {
        line += " [flags]";
    }
    line
}

/// One job's help: usage, what it does, its flags.
pub fn help(job: &Job) -> String {
    let mut text = format!("usage: {}\n\n{}\n", usage_line(job), job.about);
    if !job.flags.is_empty() {
        text += "\nflags:\n";
        for flag in job.flags {
            let name = match flag.value {
                Some(value) => format!("--{} {value}", flag.name),
                None => format!("--{}", flag.name),
            };
            text += &format!("  {name:<22} {}\n", flag.help);
        }
    }
    text
}

/// Every job, one line each.
pub fn overview(jobs: &[Job]) -> String {
    let mut text = String::from("usage: cargo xtask <job> [--help]\n\njobs:\n");
    for job in jobs {
        let first = job.about.lines().next().unwrap_or_default();
        text += &format!("  {:<14} {first}\n", job.name);
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    const JOB: Job = Job {
        name: "sweep",
        operands: &["SPEC"],
        about: "run a sweep",
        flags: &[
            Flag {
                name: "workers",
                value: Some("N"),
                help: "worker processes",
            },
            Flag {
                name: "resume",
                value: None,
                help: "finish a sweep",
            },
        ],
        run: |_| Ok(()),
    };

    fn args(list: &[&str]) -> Vec<String> {
        list.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn declared_flags_and_operands_parse() {
        let parsed = parse(&JOB, &args(&["spec.toml", "--workers", "4", "--resume"]))
            .unwrap()
            .unwrap();
        assert_eq!(parsed.operands, ["spec.toml"]);
        assert!(parsed.has("resume") && !parsed.has("out"));
        assert_eq!(parsed.flag_args(), ["--resume", "--workers", "4"]);
    }

    #[test]
    fn anything_undeclared_is_refused_with_the_help() {
        let unknown = parse(&JOB, &args(&["spec.toml", "--wrokers", "4"])).unwrap_err();
        assert!(unknown.contains("unknown flag --wrokers") && unknown.contains("--workers N"));
        let missing = parse(&JOB, &args(&["spec.toml", "--workers"])).unwrap_err();
        assert!(missing.contains("needs a value (N)"), "{missing}");
        let no_spec = parse(&JOB, &args(&["--resume"])).unwrap_err();
        assert!(
            no_spec.contains("expected 1 operand(s) (SPEC)"),
            "{no_spec}"
        );
        assert!(parse(&JOB, &args(&["--help"])).unwrap().is_none());
    }
}
