//! The bad-input campaign's judge (issue 35): what a correct tool must do
//! with a damaged drive ([`Must`]), what its message must name ([`Need`]),
//! and the class of one command's outcome ([`classify`]). The damaged drives
//! and the processes are the `bad_input_campaign` bench's; this module is
//! pure (text and numbers in, a class out), so its rules are unit-tested.

use std::fmt;

/// What a correct tool must do with one damaged drive, per command.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Must {
    /// A clear refusal, or a result within tolerance with a warning that
    /// names the damage.
    Flag,
    /// A result within tolerance with a warning naming the damage; a refusal
    /// is wrong (the data supports a result).
    Warn,
    /// A result within tolerance (the damage does not matter); a warning is
    /// allowed, a refusal is wrong.
    Clean,
    /// A result within tolerance, or a clear refusal.
    CleanOrRefuse,
    /// A clear refusal, or a result with a warning naming the damage; the
    /// result is not compared (the damage legitimately changes it, e.g. data
    /// lost).
    Notice,
    /// Only no abort; a refusal must name the damage. The result is not
    /// compared and no warning is needed (the case does not concern this
    /// command, or the drive is legitimately another one).
    Runs,
}

impl Must {
    fn refusal_allowed(self) -> bool {
        matches!(
            self,
            Must::Flag | Must::CleanOrRefuse | Must::Notice | Must::Runs
        )
    }
}

/// One thing a good message names; all of a case's needs must be met.
#[derive(Debug, Clone, PartialEq)]
pub enum Need {
    /// One of these as a word (case-insensitive; the character before it is
    /// not a letter, digit or `_`, the one after not a letter or digit, so
    /// `rl` matches `rl_rad_s` and `wheel rl` but not `c_RL`).
    Word(Vec<String>),
    /// One of these as a substring (case-insensitive).
    Sub(Vec<String>),
    /// A number within `tol` of this time (s), e.g. `t = 40.31 s`.
    Time {
        /// The time the damage is at.
        t: f64,
        /// How far a named time may be from it.
        tol: f64,
    },
}

impl Need {
    /// `Need::Word` from string slices.
    pub fn word(tokens: &[&str]) -> Need {
        Need::Word(tokens.iter().map(|s| s.to_string()).collect())
    }

    /// `Need::Sub` from string slices.
    pub fn sub(tokens: &[&str]) -> Need {
        Need::Sub(tokens.iter().map(|s| s.to_string()).collect())
    }

    /// A file line number: the 1-based line, or the data row (one less).
    pub fn line(line: usize) -> Need {
        Need::Word(vec![line.to_string(), line.saturating_sub(1).to_string()])
    }

    /// Whether `text` meets this need.
    pub fn met_by(&self, text: &str) -> bool {
        let lower = text.to_lowercase();
        match self {
            Need::Word(tokens) => tokens.iter().any(|t| has_word(&lower, &t.to_lowercase())),
            Need::Sub(tokens) => tokens.iter().any(|t| lower.contains(&t.to_lowercase())),
            Need::Time { t, tol } => numbers(text).iter().any(|x| (x - t).abs() <= *tol),
        }
    }
}

impl fmt::Display for Need {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Need::Word(t) | Need::Sub(t) => write!(f, "{}", t.join("|")),
            Need::Time { t, tol } => write!(f, "t={t:.2}±{tol}"),
        }
    }
}

fn has_word(text: &str, token: &str) -> bool {
    if token.is_empty() {
        return false;
    }
    let bytes = text.as_bytes();
    let mut from = 0;
    while let Some(k) = text[from..].find(token) {
        let start = from + k;
        let end = start + token.len();
        let before_ok = start == 0 || {
            let c = bytes[start - 1];
            !(c.is_ascii_alphanumeric() || c == b'_')
        };
        let after_ok = end >= bytes.len() || !bytes[end].is_ascii_alphanumeric();
        if before_ok && after_ok {
            return true;
        }
        from = start + 1;
        while !text.is_char_boundary(from) {
            from += 1;
        }
    }
    false
}

/// The decimal numbers in a text (`-1.5`, `40.31`, `3e2`).
pub fn numbers(text: &str) -> Vec<f64> {
    let b = text.as_bytes();
    let mut out = Vec::new();
    let mut k = 0;
    while k < b.len() {
        let starts_number = b[k].is_ascii_digit()
            || ((b[k] == b'-' || b[k] == b'+')
                && k + 1 < b.len()
                && b[k + 1].is_ascii_digit()
                && (k == 0 || !b[k - 1].is_ascii_alphanumeric()));
        if starts_number && (k == 0 || !(b[k - 1].is_ascii_alphanumeric() || b[k - 1] == b'.')) {
            let start = k;
            k += 1;
            while k < b.len() && (b[k].is_ascii_digit() || b[k] == b'.') {
                k += 1;
            }
            if let Ok(x) = text[start..k].trim_end_matches('.').parse::<f64>() {
                out.push(x);
            }
        } else {
            k += 1;
        }
    }
    out
}

/// Whether every need is met by `text`.
pub fn names_all(needs: &[Need], text: &str) -> bool {
    needs.iter().all(|n| n.met_by(text))
}

/// The class of one (case, command) outcome.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Class {
    /// Killed by a signal, a panic (exit 101), or a hang (timeout).
    Abort,
    /// Exit 0 with no warning naming the damage, and a result beyond
    /// tolerance or a case that required a refusal or warning.
    SilentWrong,
    /// Refused or warned, but the message names not all the case's needs.
    Vague,
    /// A refusal where the data supports a result (the case says so).
    RefusedWrongly,
    /// A warning naming the damage, but a result beyond tolerance.
    WarnedWrong,
    /// A clear refusal.
    OkRefused,
    /// A result within tolerance with a clear warning.
    OkWarned,
    /// The damage does not matter here and the result is within tolerance.
    OkClean,
}

impl Class {
    /// Every class, worst first.
    pub const ALL: [Class; 8] = [
        Class::Abort,
        Class::SilentWrong,
        Class::Vague,
        Class::RefusedWrongly,
        Class::WarnedWrong,
        Class::OkRefused,
        Class::OkWarned,
        Class::OkClean,
    ];

    /// The class's name in the tables.
    pub fn name(self) -> &'static str {
        match self {
            Class::Abort => "abort",
            Class::SilentWrong => "silent-wrong",
            Class::Vague => "vague",
            Class::RefusedWrongly => "refused-wrongly",
            Class::WarnedWrong => "warned-wrong",
            Class::OkRefused => "ok-refused",
            Class::OkWarned => "ok-warned",
            Class::OkClean => "ok-clean",
        }
    }

    /// Whether the outcome is what a correct tool does.
    pub fn is_ok(self) -> bool {
        matches!(self, Class::OkRefused | Class::OkWarned | Class::OkClean)
    }
}

/// How one process ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Exit {
    /// Exit code (0 = success; 101 = a Rust panic).
    Code(i32),
    /// Killed by this signal.
    Signal(i32),
    /// Still running at the time limit (killed then).
    Timeout,
}

/// One command's outcome, as the judge sees it.
#[derive(Debug, Clone)]
pub struct Outcome<'a> {
    /// How the process ended.
    pub exit: Exit,
    /// The refusal text (stderr) when it failed.
    pub refusal: &'a str,
    /// Every warning the user sees on success (JSON warnings and stderr).
    pub warnings: &'a str,
    /// On success: whether the result is within tolerance of the clean
    /// drive's (`None` when not compared), with the figures as text.
    pub within: Option<(bool, String)>,
    /// Whether some warning is new against the clean drive's (the tool
    /// noticed something, even if its message names none of the needs).
    pub new_warnings: bool,
}

/// The class of an outcome for a case that requires `must` and whose
/// message must meet `needs`, with a one-line reason.
pub fn classify(must: Must, needs: &[Need], out: &Outcome<'_>) -> (Class, String) {
    match out.exit {
        Exit::Signal(s) => (Class::Abort, format!("killed by signal {s}")),
        Exit::Timeout => (Class::Abort, "timeout (hang)".to_string()),
        Exit::Code(101) => (Class::Abort, "exit 101 (panic)".to_string()),
        Exit::Code(c) if c != 0 => {
            if !must.refusal_allowed() {
                (
                    Class::RefusedWrongly,
                    format!("exit {c}: refused, but this damage must not stop it"),
                )
            } else if names_all(needs, out.refusal) {
                (Class::OkRefused, format!("exit {c}"))
            } else {
                (
                    Class::Vague,
                    format!("exit {c}: the refusal does not name {}", list(needs)),
                )
            }
        }
        Exit::Code(_) => {
            let warned = !needs.is_empty() && names_all(needs, out.warnings);
            let (within, figures) = match &out.within {
                Some((w, f)) => (*w, f.clone()),
                None => (true, "not compared".to_string()),
            };
            let compared = !matches!(must, Must::Notice | Must::Runs);
            let within = within || !compared;
            match must {
                Must::Clean | Must::CleanOrRefuse | Must::Runs => {
                    if within {
                        let class = if warned {
                            Class::OkWarned
                        } else {
                            Class::OkClean
                        };
                        (class, figures)
                    } else if warned {
                        (Class::WarnedWrong, figures)
                    } else {
                        (Class::SilentWrong, format!("no warning; {figures}"))
                    }
                }
                Must::Flag | Must::Warn | Must::Notice => {
                    if !warned {
                        if out.new_warnings && within {
                            (
                                Class::Vague,
                                format!("warnings name not {}; {figures}", list(needs)),
                            )
                        } else {
                            (
                                Class::SilentWrong,
                                format!("no warning naming {}; {figures}", list(needs)),
                            )
                        }
                    } else if within {
                        (Class::OkWarned, figures)
                    } else {
                        (Class::WarnedWrong, figures)
                    }
                }
            }
        }
    }
}

fn list(needs: &[Need]) -> String {
    needs
        .iter()
        .map(|n| format!("[{n}]"))
        .collect::<Vec<_>>()
        .join(" and ")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ok_run<'a>(warnings: &'a str, within: bool) -> Outcome<'a> {
        Outcome {
            exit: Exit::Code(0),
            refusal: "",
            warnings,
            within: Some((within, String::new())),
            new_warnings: !warnings.is_empty(),
        }
    }

    #[test]
    fn words_do_not_match_inside_names() {
        let rl = Need::word(&["rl"]);
        assert!(rl.met_by("wheels.csv: rl_rad_s impossible"));
        assert!(rl.met_by("wheel RL at t = 3 s"));
        assert!(!rl.met_by("c_RL and c_RR are not separated"));
        assert!(!rl.met_by("world"));
        let t = Need::Time { t: 40.3, tol: 1.0 };
        assert!(t.met_by("first at t = 40.94 s"));
        assert!(!t.met_by("first at t = 42.0 s, 1e-3"));
        assert_eq!(
            numbers("a -1.5 b 40.31 s x2 7.6e16"),
            vec![-1.5, 40.31, 7.6]
        );
    }

    #[test]
    fn each_class_is_reachable() {
        let needs = [Need::word(&["rl"])];
        let panic = Outcome {
            exit: Exit::Code(101),
            refusal: "thread panicked",
            warnings: "",
            within: None,
            new_warnings: false,
        };
        assert_eq!(classify(Must::Flag, &needs, &panic).0, Class::Abort);
        let refused = Outcome {
            exit: Exit::Code(1),
            refusal: "error: wheel rl impossible",
            warnings: "",
            within: None,
            new_warnings: false,
        };
        assert_eq!(classify(Must::Flag, &needs, &refused).0, Class::OkRefused);
        assert_eq!(
            classify(Must::Warn, &needs, &refused).0,
            Class::RefusedWrongly
        );
        let vague = Outcome {
            refusal: "error: bad input",
            ..refused
        };
        assert_eq!(classify(Must::Flag, &needs, &vague).0, Class::Vague);
        assert_eq!(
            classify(Must::Flag, &needs, &ok_run("", false)).0,
            Class::SilentWrong
        );
        assert_eq!(
            classify(Must::Flag, &needs, &ok_run("", true)).0,
            Class::SilentWrong
        );
        assert_eq!(
            classify(Must::Flag, &needs, &ok_run("[x] rl glitch", true)).0,
            Class::OkWarned
        );
        assert_eq!(
            classify(Must::Flag, &needs, &ok_run("[x] something", true)).0,
            Class::Vague
        );
        let old_warning_only = Outcome {
            new_warnings: false,
            ..ok_run("[x] as on the clean drive", true)
        };
        assert_eq!(
            classify(Must::Flag, &needs, &old_warning_only).0,
            Class::SilentWrong
        );
        assert_eq!(
            classify(Must::Flag, &needs, &ok_run("[x] rl glitch", false)).0,
            Class::WarnedWrong
        );
        assert_eq!(
            classify(Must::Clean, &needs, &ok_run("", true)).0,
            Class::OkClean
        );
        assert_eq!(
            classify(Must::Clean, &needs, &ok_run("", false)).0,
            Class::SilentWrong
        );
        assert_eq!(
            classify(Must::Notice, &needs, &ok_run("[x] rl cut", false)).0,
            Class::OkWarned
        );
    }
}
