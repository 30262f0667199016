//! The residual channels and each catalogue effect's fingerprint in them.
//!
//! Channels (one row per epoch where the channel is defined):
//! - `speed`: v_gnss / v_odo - 1, where the car moves;
//! - `course_wheel`: GNSS course minus the 2W heading, block means removed
//!   (the heading's start is unknown in each block);
//! - `course_gyro`: GNSS course minus the integrated gyro, block means removed;
//! - `heading`: the absolute heading sensor minus the GNSS course;
//! - `standstill_gyro`: the gyro rate while the car stands.
//!
//! An effect is a set of columns (its fingerprint in every channel it
//! touches, one shared coefficient per column), the physical parameters its
//! coefficients stand for, and the range a passenger car's value lies in.
//! Nuisance columns (the common scale of the circumferences and their
//! left/right difference) are always in the model: the calibration fits them.

use super::epochs::{Epoch, Epochs};
use super::locate::{align_with_angle, dr_points, Context, DrPoints, HeadingSource, Model};
use interfaces::effects::{Effect, Param as EffectParam};
use stats::mad_sigma;
use vehicle_model::effects::READS_LATERAL_ACCELERATION;

/// A residual channel.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Channel {
    /// v_gnss / v_odo - 1.
    Speed,
    /// GNSS course - 2W heading.
    CourseWheel,
    /// GNSS course - gyro heading.
    CourseGyro,
    /// Heading sensor - GNSS course.
    Heading,
    /// Gyro rate at standstill.
    StandstillGyro,
    /// GNSS position against the 2W model dead-reckoned over each block
    /// (the block's rigid placement out).
    Position,
    /// GNSS position against the gyro-heading dead-reckoning over each block.
    PositionGyro,
}

impl Channel {
    /// Name in reports.
    pub fn name(self) -> &'static str {
        match self {
            Channel::Speed => "speed",
            Channel::CourseWheel => "course_wheel",
            Channel::CourseGyro => "course_gyro",
            Channel::Heading => "heading",
            Channel::StandstillGyro => "standstill_gyro",
            Channel::Position => "position",
            Channel::PositionGyro => "position_gyro",
        }
    }

    /// Unit of the channel's residual.
    pub fn unit(self) -> &'static str {
        match self {
            Channel::Speed => "1 (relative speed)",
            Channel::CourseWheel | Channel::CourseGyro | Channel::Heading => "rad",
            Channel::StandstillGyro => "rad/s",
            Channel::Position | Channel::PositionGyro => "m",
        }
    }

    /// Block means are removed from this channel.
    fn demeaned(self) -> bool {
        matches!(self, Channel::CourseWheel | Channel::CourseGyro)
    }

    /// Every channel.
    pub const ALL: [Channel; 7] = [
        Channel::Position,
        Channel::PositionGyro,
        Channel::Speed,
        Channel::CourseWheel,
        Channel::CourseGyro,
        Channel::Heading,
        Channel::StandstillGyro,
    ];
}

/// One physical parameter of an effect: the coefficient of a column.
#[derive(Debug, Clone, PartialEq)]
pub struct Param {
    /// The effect table's parameter (its name, unit, display scale and
    /// typical size).
    pub param: EffectParam,
    /// The coefficient's name in messages (the table's model name, or
    /// `gain_squared`).
    pub name: &'static str,
    /// The coefficient's unit.
    pub unit: &'static str,
    /// The column fits the square of the parameter (road grade's gain:
    /// small grades act through cos(g x) ~ 1 - g^2 x^2 / 2).
    pub squared: bool,
    /// Which column's coefficient it is.
    pub column: usize,
    /// The smallest and largest coefficient a passenger car plausibly has
    /// (the table's plausible range).
    pub range: (f64, f64),
}

impl Param {
    /// The parameter fitted by `column`, as the table says.
    pub(super) fn of(param: EffectParam, column: usize) -> Param {
        let spec = param.spec();
        Param {
            param,
            name: spec.model_name,
            unit: spec.model_unit,
            squared: false,
            column,
            range: spec.plausible,
        }
    }

    /// The model (SI) value of the parameter from the column's coefficient.
    pub fn model_value(&self, coefficient: f64) -> f64 {
        if self.squared {
            coefficient.max(0.0).sqrt()
        } else {
            coefficient
        }
    }

    /// A coefficient and its sigma as reported (the table's unit; the
    /// square root of a squared one, its sigma by the delta method).
    pub fn reported(&self, coefficient: f64, sigma: f64) -> (f64, f64) {
        if self.squared {
            let g = coefficient.max(0.0).sqrt();
            (g, if g > 0.0 { sigma / (2.0 * g) } else { sigma })
        } else {
            (
                self.param.to_display(coefficient),
                self.param.to_display(sigma),
            )
        }
    }
}

/// What moving a column's coefficient does to the dead-reckoning model
/// (the position channels' columns are finite differences of it).
#[derive(Debug, Clone, Copy, PartialEq)]
enum Kick {
    /// Nothing (the column does not act on the dead-reckoning).
    None,
    /// Both circumferences' common scale.
    Scale,
    /// Their left/right difference.
    LeftRight,
    /// One term by a step, with another term set alongside (the drift's
    /// time constant) and the longitudinal slip's side.
    Term {
        param: EffectParam,
        step: f64,
        with: Option<(EffectParam, f64)>,
        slip_side: i8,
    },
}

impl Kick {
    /// Whether the dead-reckoning it moves reads the lateral acceleration.
    fn reads_lateral_acceleration(&self) -> bool {
        matches!(self, Kick::Term { param, .. } if READS_LATERAL_ACCELERATION.contains(param))
    }

    fn term(param: EffectParam, step: f64) -> Kick {
        Kick::Term {
            param,
            step,
            with: None,
            slip_side: 0,
        }
    }
}

/// A candidate effect: its columns in the design and what they mean.
#[derive(Debug, Clone, PartialEq)]
pub struct Candidate {
    /// The catalogue effect.
    pub effect: Effect,
    /// A variant of its form (`time_constant_s=600`), empty if none.
    pub variant: String,
    /// Column indices (into [`Design::columns`]).
    pub columns: Vec<usize>,
    /// The parameters, one per column.
    pub params: Vec<Param>,
}

/// The stacked regression problem of a drive.
#[derive(Debug, Clone)]
pub struct Design {
    /// Per row: channel, epoch index, block.
    pub rows: Vec<(Channel, usize, usize)>,
    /// Residual per row (block means removed where the channel says so).
    pub y: Vec<f64>,
    /// Weight per row (1 / noise variance, from the drive's own scatter).
    pub w: Vec<f64>,
    /// Columns: per column, one value per row.
    pub columns: Vec<Vec<f64>>,
    /// Column names, for messages.
    pub column_names: Vec<String>,
    /// The nuisance columns (always in the model).
    pub nuisance: Vec<usize>,
    /// The candidate effects.
    pub candidates: Vec<Candidate>,
    /// Effects that this drive cannot test, with what it lacks.
    pub untestable: Vec<(Effect, String)>,
    /// Number of blocks.
    pub blocks: usize,
    /// Block length, s.
    pub block_s: f64,
    /// Noise sigma per channel (in channel units, at unit row weight; the
    /// position channels after whitening).
    pub channel_sigma: Vec<(Channel, f64)>,
    /// The AR(1) coefficient the position channels were whitened with.
    pub whitening: Vec<(Channel, f64)>,
}

/// Settings of the design.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DesignSettings {
    /// Block length, s.
    pub block_s: f64,
    /// Below this speed the course is not used, m/s.
    pub min_speed_m_s: f64,
    /// The plain model's (nominal) rear track, m.
    pub track_width_m: f64,
}

/// The drive's epochs as a regression problem.
pub fn build(
    ep: &Epochs,
    settings: &DesignSettings,
    excluded: &[bool],
    cx: &Context<'_>,
    base: &Model,
) -> Design {
    build_reusing(ep, settings, excluded, cx, base, None).0
}

/// The plain model's dead-reckoning of every block under each heading
/// source, as [`build_keeping_points`] made it (`None` where a block has
/// none): what [`rebuild_lateral`] needs to place the columns it recomputes.
#[derive(Debug, Clone, Default)]
pub struct BasePoints(Vec<Option<DrPoints>>);

/// [`build`], keeping the plain model's dead-reckoning for a
/// [`rebuild_lateral`].
pub fn build_keeping_points(
    ep: &Epochs,
    settings: &DesignSettings,
    excluded: &[bool],
    cx: &Context<'_>,
    base: &Model,
) -> (Design, BasePoints) {
    build_reusing(ep, settings, excluded, cx, base, None)
}

/// The design again after the epochs' lateral acceleration was read anew
/// (through a load transfer's estimate): only the columns that read a_y
/// (side-slip, load transfer) are computed; every other column is the same
/// as in `old`, built from the same drive with the same plain `base` model
/// (which reads no a_y), and is taken from it, as are the plain model's
/// dead-reckonings (`points`).
pub fn rebuild_lateral(
    old: &Design,
    points: &BasePoints,
    ep: &Epochs,
    settings: &DesignSettings,
    excluded: &[bool],
    cx: &Context<'_>,
    base: &Model,
) -> Design {
    build_reusing(ep, settings, excluded, cx, base, Some((old, points))).0
}

fn build_reusing(
    ep: &Epochs,
    settings: &DesignSettings,
    excluded: &[bool],
    cx: &Context<'_>,
    base: &Model,
    reuse: Option<(&Design, &BasePoints)>,
) -> (Design, BasePoints) {
    let mut points = BasePoints::default();
    let e = &ep.epochs;
    let t0 = e.first().map_or(0.0, |x| x.t_s);
    let block_of = |x: &Epoch| ((x.t_s - t0) / settings.block_s).floor().max(0.0) as usize;
    let blocks = e.last().map_or(0, |x| block_of(x) + 1);
    // Rows.
    let mut rows = Vec::new();
    let mut y = Vec::new();
    let mut wrel = Vec::new();
    let moving = |x: &Epoch| !x.standstill && x.v_odo > settings.min_speed_m_s;
    // Continuous (unwrapped) course residuals.
    let mut last_cw: Option<f64> = None;
    let mut last_cg: Option<f64> = None;
    for (i, x) in e.iter().enumerate() {
        if excluded[i] {
            continue;
        }
        let b = block_of(x);
        // GNSS velocity noise: sqrt(2) sigma / dt; relative to v.
        let vnoise = std::f64::consts::SQRT_2 * ep.gnss_sigma_m / x.dt_s;
        if moving(x) && x.v_gnss > 0.0 {
            let rel = vnoise / x.v_odo;
            rows.push((Channel::Speed, i, b));
            // Chord against chord (`Epoch::v_chord`): the columns' scale
            // terms are relative to the wheels' arc, the same to first order.
            y.push(x.v_gnss / x.v_chord - 1.0);
            wrel.push(1.0 / (rel * rel + 1e-8));
            let cw = unwrap_near(x.course_gnss - x.course_odo, last_cw);
            last_cw = Some(cw);
            rows.push((Channel::CourseWheel, i, b));
            y.push(cw);
            wrel.push(1.0 / (rel * rel + 1e-8));
            if ep.has_gyro && x.course_gyro.is_finite() {
                let cg = unwrap_near(x.course_gnss - x.course_gyro, last_cg);
                last_cg = Some(cg);
                rows.push((Channel::CourseGyro, i, b));
                y.push(cg);
                wrel.push(1.0 / (rel * rel + 1e-8));
            }
            if ep.has_heading && x.heading.is_finite() {
                // The sensor reads the heading at the fix, the GNSS course
                // is the chord over the interval: the chord's departure
                // from the heading, as the gyro (else the wheels) shapes
                // it, is taken back out.
                let chord_minus_heading = if x.course_gyro.is_finite() && x.psi_gyro.is_finite() {
                    x.course_gyro - x.psi_gyro
                } else {
                    x.course_odo - x.psi_odo
                };
                rows.push((Channel::Heading, i, b));
                y.push(vehicle_model::two_wheel::wrap_angle(
                    x.heading - (x.course_gnss - chord_minus_heading),
                ));
                wrel.push(1.0 / (rel * rel + 1e-6));
            }
        } else if x.standstill && ep.has_gyro && x.gz.is_finite() {
            rows.push((Channel::StandstillGyro, i, b));
            y.push(x.gz);
            wrel.push(1.0);
        }
    }
    let mut columns: Vec<Vec<f64>> = Vec::new();
    let mut names: Vec<String> = Vec::new();
    let mut kicks: Vec<Kick> = Vec::new();
    let mut add = |name: String, kick: Kick, f: &dyn Fn(Channel, &Epoch) -> f64| -> usize {
        let col: Vec<f64> = rows.iter().map(|&(c, i, _)| f(c, &e[i])).collect();
        columns.push(col);
        names.push(name);
        kicks.push(kick);
        columns.len() - 1
    };
    // Nuisance: the common scale (speed) and the left/right difference
    // (a heading that grows with distance).
    let scale = add("common_scale".into(), Kick::None, &|c, _| {
        f64::from(c == Channel::Speed)
    });
    let lr = add("left_right".into(), Kick::None, &|c, x| {
        if c == Channel::CourseWheel {
            x.s_m
        } else {
            0.0
        }
    });
    let mut candidates = Vec::new();
    let mut untestable = Vec::new();
    let track = settings.track_width_m;
    let course = |c: Channel| matches!(c, Channel::CourseWheel | Channel::CourseGyro);

    // side_slip: course = heading + beta, beta = -k a_y.
    let col = add(
        Effect::SideSlip.id().into(),
        Kick::term(EffectParam::SideSlipGain, 0.004),
        &|c, x| {
            if course(c) {
                -x.a_y
            } else if c == Channel::Heading {
                x.a_y
            } else {
                0.0
            }
        },
    );
    candidates.push(single(Effect::SideSlip, col));
    // load_transfer_radius: heading error -(2 k_z / t) int a_y ds.
    let col = add(
        Effect::LoadTransferRadius.id().into(),
        Kick::term(EffectParam::LoadTransferGain, 1e-4),
        &|c, x| {
            if c == Channel::CourseWheel {
                -2.0 / track * x.int_ay_ds
            } else {
                0.0
            }
        },
    );
    candidates.push(single(Effect::LoadTransferRadius, col));
    // speed_radius_growth: relative speed k_v v^2.
    let col = add(
        Effect::SpeedRadiusGrowth.id().into(),
        Kick::term(EffectParam::SpeedGrowthGain, 2.5e-6),
        &|c, x| {
            if c == Channel::Speed {
                x.v_odo * x.v_odo
            } else {
                0.0
            }
        },
    );
    candidates.push(single(Effect::SpeedRadiusGrowth, col));
    // longitudinal_slip: wheels turn as if v (1 + k_s a_x); both signs, or
    // one (an axle that is not driven slips when braking only).
    for (variant, slip_side, f) in [
        ("", 0, (|a: f64| a) as fn(f64) -> f64),
        ("braking only", -1, |a: f64| a.min(0.0)),
        ("driving only", 1, |a: f64| a.max(0.0)),
    ] {
        let kick = Kick::Term {
            param: EffectParam::LongitudinalSlipGain,
            step: 0.002,
            with: None,
            slip_side,
        };
        let col = add(
            format!("{} {variant}", Effect::LongitudinalSlip),
            kick,
            &|c, x| {
                if c == Channel::Speed {
                    -f(x.a_x)
                } else {
                    0.0
                }
            },
        );
        let mut cand = single(Effect::LongitudinalSlip, col);
        cand.variant = variant.to_string();
        candidates.push(cand);
    }
    // track_width: true heading = 2W heading / (1 + rel).
    let col = add(
        Effect::TrackWidth.id().into(),
        Kick::term(EffectParam::TrackRel, 0.02),
        &|c, x| {
            if c == Channel::CourseWheel {
                -x.psi_odo
            } else {
                0.0
            }
        },
    );
    candidates.push(single(Effect::TrackWidth, col));
    if ep.has_gyro {
        // gyro_bias: gyro heading gains b t; at standstill the rate is b.
        let col = add(
            Effect::GyroBias.id().into(),
            Kick::term(EffectParam::GyroBias, 1e-4),
            &|c, x| match c {
                Channel::CourseGyro => -x.t_rel_s,
                Channel::StandstillGyro => 1.0,
                _ => 0.0,
            },
        );
        candidates.push(single(Effect::GyroBias, col));
        let col = add(
            Effect::GyroScale.id().into(),
            Kick::term(EffectParam::GyroScale, 0.005),
            &|c, x| {
                if c == Channel::CourseGyro {
                    -x.psi_gyro
                } else {
                    0.0
                }
            },
        );
        candidates.push(single(Effect::GyroScale, col));
    } else {
        untestable.push((Effect::GyroBias, "a yaw-rate gyro (imu.csv)".to_string()));
        untestable.push((Effect::GyroScale, "a yaw-rate gyro (imu.csv)".to_string()));
    }
    // gnss_latency: GNSS describes t - tau: speed -tau a_x / v, course -tau w.
    let col = add(
        Effect::GnssLatency.id().into(),
        Kick::term(EffectParam::GnssLatency, 0.08),
        &|c, x| match c {
            Channel::Speed => -x.a_x / x.v_odo,
            Channel::CourseWheel | Channel::CourseGyro => -x.w_odo,
            Channel::Heading => x.w_odo,
            _ => 0.0,
        },
    );
    candidates.push(single(Effect::GnssLatency, col));
    // gnss_lever_arm: antenna velocity (v - w l_y, w l_x).
    let lx = add(
        format!("{} x", Effect::GnssLeverArm),
        Kick::term(EffectParam::LeverArmX, 1.0),
        &|c, x| match c {
            Channel::CourseWheel | Channel::CourseGyro => x.w_odo / x.v_odo,
            Channel::Heading => -x.w_odo / x.v_odo,
            _ => 0.0,
        },
    );
    let ly = add(
        format!("{} y", Effect::GnssLeverArm),
        Kick::term(EffectParam::LeverArmY, 1.0),
        &|c, x| {
            if c == Channel::Speed {
                -x.w_odo / x.v_odo
            } else {
                0.0
            }
        },
    );
    candidates.push(Candidate {
        effect: Effect::GnssLeverArm,
        variant: String::new(),
        columns: vec![lx, ly],
        params: vec![
            Param::of(EffectParam::LeverArmX, lx),
            Param::of(EffectParam::LeverArmY, ly),
        ],
    });
    // radius_drift: relative speed d (1 - exp(-t/T)); T from a grid, only
    // time constants the drive is long enough to see.
    let duration = e.last().map_or(0.0, |x| x.t_rel_s);
    for t_c in [300.0, 600.0, 1200.0, 2400.0] {
        if t_c > 2.0 * duration {
            continue;
        }
        let kick = Kick::Term {
            param: EffectParam::DriftFraction,
            step: 0.003,
            with: Some((EffectParam::DriftTimeConstant, t_c)),
            slip_side: 0,
        };
        let col = add(format!("{} T={t_c}", Effect::RadiusDrift), kick, &|c, x| {
            if c == Channel::Speed {
                1.0 - (-x.t_rel_s / t_c).exp()
            } else {
                0.0
            }
        });
        let mut cand = single(Effect::RadiusDrift, col);
        cand.variant = format!("{}={t_c}", EffectParam::DriftTimeConstant.spec().name);
        candidates.push(cand);
    }
    if duration < 150.0 {
        untestable.push((
            Effect::RadiusDrift,
            "a drive of at least 150 s (a warm-up takes minutes)".to_string(),
        ));
    }
    if ep.has_grade {
        // road_grade: horizontal speed = wheel speed cos(gamma) ~ 1 - gamma^2 / 2.
        let col = add(
            Effect::RoadGrade.id().into(),
            // The column is per unit of gain^2 (small grades: cos(g x) ~ 1 - g^2 x^2 / 2).
            Kick::term(EffectParam::GradeGain, 1.0),
            &|c, x| {
                if c == Channel::Speed && x.grade.is_finite() {
                    -0.5 * x.grade * x.grade
                } else {
                    0.0
                }
            },
        );
        let mut cand = single(Effect::RoadGrade, col);
        // The column fits gain^2: plausible from 0.1 to 10 (the table's
        // range of the gain, squared).
        cand.params[0] = Param {
            name: "gain_squared",
            squared: true,
            range: (0.1, 10.0),
            ..Param::of(EffectParam::GradeGain, col)
        };
        candidates.push(cand);
    } else {
        untestable.push((
            Effect::RoadGrade,
            "a forward accelerometer aligned with the car (imu.csv ax_m_s2) to read the slope"
                .to_string(),
        ));
    }
    if ep.has_heading {
        let a = add(format!("{} A", Effect::HeadingBias), Kick::None, &|c, _| {
            f64::from(c == Channel::Heading)
        });
        let b = add(format!("{} B", Effect::HeadingBias), Kick::None, &|c, x| {
            if c == Channel::Heading {
                x.course_gnss.sin()
            } else {
                0.0
            }
        });
        let cc = add(format!("{} C", Effect::HeadingBias), Kick::None, &|c, x| {
            if c == Channel::Heading {
                x.course_gnss.cos()
            } else {
                0.0
            }
        });
        candidates.push(Candidate {
            effect: Effect::HeadingBias,
            variant: String::new(),
            columns: vec![a, b, cc],
            params: vec![
                Param::of(EffectParam::HeadingA, a),
                Param::of(EffectParam::HeadingB, b),
                Param::of(EffectParam::HeadingC, cc),
            ],
        });
    } else {
        untestable.push((
            Effect::HeadingBias,
            "an absolute heading sensor (heading.csv)".to_string(),
        ));
    }

    // Position channels: each block dead-reckoned from a zero pose, laid
    // onto its fixes by the best rigid motion; the columns are the change of
    // the laid model points per unit of each coefficient (finite differences
    // of the dead-reckoning), with the block's rigid motion projected out.
    let scale_col = add("position_scale".into(), Kick::Scale, &|_, _| 0.0);
    let lr_col = add("position_left_right".into(), Kick::LeftRight, &|_, _| 0.0);
    let nuisance = vec![scale, lr, scale_col, lr_col];
    let reused = |k: &Kick| reuse.is_some() && !k.reads_lateral_acceleration();
    let perturb: Vec<Option<(Model, f64)>> = kicks
        .iter()
        .map(|k| {
            if reused(k) {
                None
            } else {
                perturbation(*k, base)
            }
        })
        .collect();
    let mut sources = vec![(Channel::Position, HeadingSource::Wheels)];
    if ep.has_gyro {
        sources.push((Channel::PositionGyro, HeadingSource::Gyro));
    }
    let first_t = t0;
    for b in 0..blocks {
        let (b0, b1) = (
            first_t + b as f64 * settings.block_s,
            first_t + (b + 1) as f64 * settings.block_s,
        );
        for &(ch, source) in &sources {
            let slot = points.0.len();
            let cached = reuse.and_then(|(_, p)| p.0.get(slot).cloned());
            points.0.push(match cached {
                Some(known) => known,
                None => dr_points(base, source, cx, b0, b1),
            });
            let Some(base_pts) = points.0.get(slot).and_then(Option::as_ref) else {
                continue;
            };
            let (g, p0) = (&base_pts.gnss, &base_pts.model);
            if g.len() < 5 {
                continue;
            }
            let (laid, _, th) = align_with_angle(p0, g);
            let (sn, cs) = th.sin_cos();
            let m = g.len();
            // Rows x0, y0, x1, y1, ...
            let mut ry = Vec::with_capacity(2 * m);
            for i in 0..m {
                ry.push(g[i][0] - laid[i][0]);
                ry.push(g[i][1] - laid[i][1]);
            }
            let mut cols_here: Vec<Vec<f64>> = vec![vec![0.0; 2 * m]; columns.len()];
            for (c, pert) in perturb.iter().enumerate() {
                let Some((model, delta)) = pert else {
                    continue;
                };
                let Some(pert_pts) = dr_points(model, source, cx, b0, b1) else {
                    continue;
                };
                let p1 = &pert_pts.model;
                if p1.len() != m {
                    continue;
                }
                for i in 0..m {
                    let dx = (p1[i][0] - p0[i][0]) / delta;
                    let dy = (p1[i][1] - p0[i][1]) / delta;
                    cols_here[c][2 * i] = cs * dx - sn * dy;
                    cols_here[c][2 * i + 1] = sn * dx + cs * dy;
                }
            }
            // Project out the block's rigid motion (two shifts, one turn
            // about the centroid).
            let (mx, my) = laid.iter().fold((0.0, 0.0), |a, p| {
                (a.0 + p[0] / m as f64, a.1 + p[1] / m as f64)
            });
            let mut basis: Vec<Vec<f64>> = vec![
                (0..2 * m).map(|r| f64::from(r % 2 == 0)).collect(),
                (0..2 * m).map(|r| f64::from(r % 2 == 1)).collect(),
                (0..2 * m)
                    .map(|r| {
                        let p = laid[r / 2];
                        if r % 2 == 0 {
                            -(p[1] - my)
                        } else {
                            p[0] - mx
                        }
                    })
                    .collect(),
            ];
            orthonormalise(&mut basis);
            project_out(&basis, &mut ry);
            for col in cols_here.iter_mut() {
                project_out(&basis, col);
            }
            let ep_index = |i: usize| {
                let t = base_pts.t[i];
                e.partition_point(|x| x.t_s < t)
                    .min(e.len().saturating_sub(1))
            };
            for i in 0..2 * m {
                rows.push((ch, ep_index(i / 2), b));
                y.push(ry[i]);
                wrel.push(1.0);
                for (c, col) in columns.iter_mut().enumerate() {
                    col.push(cols_here[c][i]);
                }
            }
        }
    }
    let n = rows.len();
    // GNSS errors are correlated in time: whiten the position channels with
    // an AR(1) model whose coefficient is measured on this drive (the lag-1
    // autocorrelation of the residual, per axis within blocks), then weigh
    // by the scatter of what is left.
    let mut whitening = Vec::new();
    for ch in [Channel::Position, Channel::PositionGyro] {
        let idx: Vec<usize> = (0..n).filter(|&r| rows[r].0 == ch).collect();
        // Same axis, next fix: two rows on, in the same block.
        let pairs: Vec<(usize, usize)> = idx
            .windows(3)
            .filter(|w| rows[w[0]].2 == rows[w[2]].2)
            .map(|w| (w[0], w[2]))
            .collect();
        let (mut sxy, mut sxx) = (0.0, 0.0);
        for &(a, b) in &pairs {
            sxy += y[a] * y[b];
            sxx += y[a] * y[a];
        }
        let phi = if sxx > 0.0 {
            (sxy / sxx).clamp(0.0, 0.99)
        } else {
            0.0
        };
        whitening.push((ch, phi));
        if phi == 0.0 {
            continue;
        }
        let scale0 = (1.0 - phi * phi).sqrt();
        let transform = |v: &mut Vec<f64>| {
            // Backwards, so that each row uses its predecessor's raw value.
            for k in (0..idx.len()).rev() {
                let r = idx[k];
                let prev = (k >= 2 && rows[idx[k - 2]].2 == rows[r].2).then(|| idx[k - 2]);
                match prev {
                    Some(p) => v[r] -= phi * v[p],
                    None => v[r] *= scale0,
                }
            }
        };
        transform(&mut y);
        for (c, col) in columns.iter_mut().enumerate() {
            // A reused column is taken whole from the old design below.
            if !reused(&kicks[c]) {
                transform(col);
            }
        }
    }

    // Block means out of the demeaned channels (y and every column).
    let mut sums: std::collections::BTreeMap<(Channel, usize), (f64, f64)> = Default::default();
    let mut demean = |v: &mut Vec<f64>| {
        sums.clear();
        for (r, &(c, _, b)) in rows.iter().enumerate() {
            if c.demeaned() {
                let s = sums.entry((c, b)).or_insert((0.0, 0.0));
                s.0 += wrel[r] * v[r];
                s.1 += wrel[r];
            }
        }
        for (r, &(c, _, b)) in rows.iter().enumerate() {
            if c.demeaned() {
                if let Some(&(sv, sw)) = sums.get(&(c, b)) {
                    v[r] -= sv / sw;
                }
            }
        }
    };
    demean(&mut y);
    for (c, col) in columns.iter_mut().enumerate() {
        match reuse.and_then(|(old, _)| old.columns.get(c)) {
            Some(o) if reused(&kicks[c]) && o.len() == col.len() => col.clone_from(o),
            _ => demean(col),
        }
    }
    // Each effect as the gyro's heading sees it: the same columns without
    // the wheels' heading channels. Where the tyres turn the wheels'
    // heading beyond the model (their own compliance, a load transfer not
    // linear in a_y), those channels pull one coefficient away from what
    // the gyro's channels show, and the held-out test of the whole column
    // refuses an effect the gyro's dead-reckoning plainly holds (measured
    // first on the side-slip). The Wald decision tries the variant for an
    // effect decided under the gyro's heading ([`super::decide`]). Track
    // width and the compass's bias live in the wheels' heading and the
    // heading channel: they have none.
    if ep.has_gyro {
        let whole: Vec<Candidate> = candidates
            .iter()
            .filter(|c| {
                !c.seen_by_gyro() && !matches!(c.effect, Effect::TrackWidth | Effect::HeadingBias)
            })
            .cloned()
            .collect();
        for cand in whole {
            let zeroed: Vec<Vec<f64>> = cand
                .columns
                .iter()
                .map(|&k| {
                    columns[k]
                        .iter()
                        .zip(&rows)
                        .map(|(v, (c, _, _))| match c {
                            Channel::CourseWheel | Channel::Position => 0.0,
                            _ => *v,
                        })
                        .collect()
                })
                .collect();
            // Only where the wheels' channels held some of it, and the
            // gyro's hold the rest.
            let changed = cand
                .columns
                .iter()
                .zip(&zeroed)
                .any(|(&k, z)| columns[k] != *z);
            let alive = zeroed.iter().all(|z| z.iter().any(|v| *v != 0.0));
            if !(changed && alive) {
                continue;
            }
            let mut params = cand.params.clone();
            let mut cols = Vec::new();
            for ((&k, z), p) in cand.columns.iter().zip(zeroed).zip(params.iter_mut()) {
                columns.push(z);
                names.push(format!("{} (gyro heading)", names[k]));
                let c = columns.len() - 1;
                p.column = c;
                cols.push(c);
            }
            candidates.push(Candidate {
                effect: cand.effect,
                variant: if cand.variant.is_empty() {
                    SEEN_BY_GYRO.to_string()
                } else {
                    format!("{}, {SEEN_BY_GYRO}", cand.variant)
                },
                columns: cols,
                params,
            });
        }
    }
    // Channel noise from the drive itself: the scatter of first differences
    // of the weighted residual (smooth structure cancels, white noise stays).
    let mut channel_sigma = Vec::new();
    let mut w = vec![0.0; n];
    for ch in Channel::ALL {
        let idx: Vec<usize> = (0..n).filter(|&r| rows[r].0 == ch).collect();
        if idx.is_empty() {
            continue;
        }
        let d: Vec<f64> = idx
            .windows(2)
            .filter(|p| rows[p[0]].2 == rows[p[1]].2)
            .map(|p| y[p[1]] * wrel[p[1]].sqrt() - y[p[0]] * wrel[p[0]].sqrt())
            .collect();
        let mut s = if matches!(ch, Channel::Position | Channel::PositionGyro) {
            // Whitened: the scatter of the rows themselves.
            let v: Vec<f64> = idx.iter().map(|&r| y[r]).collect();
            mad_sigma(&v)
        } else {
            mad_sigma(&d) / std::f64::consts::SQRT_2
        };
        if !(s.is_finite() && s > 0.0) {
            s = 1.0;
        }
        for &r in &idx {
            w[r] = wrel[r] / (s * s);
        }
        channel_sigma.push((ch, s));
    }
    // Candidates whose columns carry nothing on this drive are untestable.
    candidates.retain(|cand| {
        let energy: f64 = cand
            .columns
            .iter()
            .map(|&c| (0..n).map(|r| w[r] * columns[c][r].powi(2)).sum::<f64>())
            .fold(f64::INFINITY, f64::min);
        let ok = energy.is_finite() && energy > 1e-9;
        if !ok && !untestable.iter().any(|(e, _)| *e == cand.effect) {
            untestable.push((cand.effect, cand.effect.spec().needs.to_string()));
        }
        ok
    });
    let design = Design {
        rows,
        y,
        w,
        columns,
        column_names: names,
        nuisance,
        candidates,
        untestable,
        blocks,
        block_s: settings.block_s,
        channel_sigma,
        whitening,
    };
    (design, points)
}

/// The variant of an effect fitted on the gyro's heading channels only
/// (alone, or after the effect's own variant and a comma).
pub const SEEN_BY_GYRO: &str = "seen_by=gyro_heading";

impl Design {
    /// The channels whose rows carry any of `cand`'s columns: where its
    /// fingerprint is, on this drive.
    pub fn channels_of(&self, cand: &Candidate) -> Vec<Channel> {
        let mut out: Vec<Channel> = Vec::new();
        for &c in &cand.columns {
            let Some(col) = self.columns.get(c) else {
                continue;
            };
            for ((ch, _, _), v) in self.rows.iter().zip(col) {
                if *v != 0.0 && v.is_finite() && !out.contains(ch) {
                    out.push(*ch);
                }
            }
        }
        out.sort();
        out
    }
}

impl Candidate {
    /// Whether it is an effect's variant fitted on the gyro's heading
    /// channels only ([`SEEN_BY_GYRO`]).
    pub fn seen_by_gyro(&self) -> bool {
        self.variant.ends_with(SEEN_BY_GYRO)
    }
}

/// A candidate with one column: the effect's main fitted parameter.
fn single(effect: Effect, column: usize) -> Candidate {
    Candidate {
        effect,
        variant: String::new(),
        columns: vec![column],
        params: vec![Param::of(effect.main_fitted(), column)],
    }
}

/// Keep a course residual continuous with the previous one (no 2 pi jumps).
fn unwrap_near(a: f64, prev: Option<f64>) -> f64 {
    match prev {
        Some(p) => p + vehicle_model::two_wheel::wrap_angle(a - p),
        None => vehicle_model::two_wheel::wrap_angle(a),
    }
}

/// The model with one coefficient moved by a small step, and the step; `None`
/// for columns that do not act on the dead-reckoning.
fn perturbation(kick: Kick, base: &Model) -> Option<(Model, f64)> {
    let mut m = *base;
    let d = 1e-3;
    match kick {
        Kick::None => None,
        Kick::Scale => {
            m.c_rl *= 1.0 + d;
            m.c_rr *= 1.0 + d;
            Some((m, d))
        }
        Kick::LeftRight => {
            m.c_rl *= 1.0 - d;
            m.c_rr *= 1.0 + d;
            Some((m, d))
        }
        Kick::Term {
            param,
            step,
            with,
            slip_side,
        } => {
            m.terms.set(param, step);
            if let Some((other, v)) = with {
                m.terms.set(other, v);
            }
            if slip_side != 0 {
                m.slip_side = slip_side;
            }
            Some((m, step))
        }
    }
}

/// Gram-Schmidt: make the vectors orthonormal (dropping dependent ones).
fn orthonormalise(basis: &mut Vec<Vec<f64>>) {
    let mut out: Vec<Vec<f64>> = Vec::new();
    for v in basis.iter() {
        let mut u = v.clone();
        for q in &out {
            let d: f64 = u.iter().zip(q).map(|(a, b)| a * b).sum();
            for (a, b) in u.iter_mut().zip(q) {
                *a -= d * b;
            }
        }
        let norm = u.iter().map(|a| a * a).sum::<f64>().sqrt();
        if norm > 1e-9 {
            out.push(u.iter().map(|a| a / norm).collect());
        }
    }
    *basis = out;
}

/// Remove from `v` its components along the orthonormal `basis`.
fn project_out(basis: &[Vec<f64>], v: &mut [f64]) {
    for q in basis {
        let d: f64 = v.iter().zip(q).map(|(a, b)| a * b).sum();
        for (a, b) in v.iter_mut().zip(q) {
            *a -= d * b;
        }
    }
}
