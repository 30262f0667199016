//! The fault suite, short: one simulated drive with a GNSS outage, the
//! odometry killed twice and the calibrator once at moments drawn from a
//! fixed seed, each started again at once (see
//! `integration_tests::faults`). The long run over several seeds is
//! `cargo bench -p integration-tests --bench fault_kills`.

use integration_tests::faults::{run_faults, FaultConfig};
use simulator::Scenario;

#[test]
fn services_killed_at_random_moments_come_back_and_never_lie() {
    let config = FaultConfig {
        seed: 11,
        scenario: Scenario::Paper,
        odometry_kills: 2,
        calibrator_kills: 1,
        speed: 10.0,
        outage: (0.45, 0.75),
    };
    let r = run_faults(&config);
    eprintln!("{r:#?}");
    assert_eq!(
        r.kills,
        (2, 1),
        "every kill was done before the drive ended"
    );
    assert_eq!(r.survived, 3, "every restarted service came back");
    assert_eq!(r.poses_lost, 0, "no pose lost on the bus");
    assert!(r.estimates_kept, "estimate versions: {:?}", r.versions);
    assert_eq!(r.first_poses.len(), 2, "{r:?}");
    for (t, mode, e, sigma, d) in &r.first_poses {
        assert!(
            *d <= 3.0,
            "the first pose after a restart (t = {t} s, {mode:?}) is {e} m off with sigma {sigma} m"
        );
    }
    // A consistent filter has 1.1 % of its poses beyond their 3-sigma
    // ellipse; a restart must not make that much worse.
    assert!(r.judged_after_restart > 100, "{r:?}");
    let share = r.beyond_3_sigma_after_restart as f64 / r.judged_after_restart as f64;
    assert!(
        share <= 0.03,
        "{:.1} % of the poses after restarts beyond their 3-sigma ellipse (worst {:?})",
        100.0 * share,
        r.worst_after_restart
    );
}
