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
    assert_eq!(r.kills, (2, 1), "every kill was done before the drive ended");
    assert_eq!(r.survived, 3, "every restarted service came back");
    assert_eq!(r.poses_lost, 0, "no pose lost on the bus");
    assert!(r.estimates_kept, "estimate versions: {:?}", r.versions);
    assert!(r.judged_after_restart > 100, "{r:?}");
    assert_eq!(
        r.beyond_3_sigma_after_restart, 0,
        "a pose after a restart outside its own 3-sigma ellipse: worst {:?}",
        r.worst_after_restart
    );
}
