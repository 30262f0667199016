//! The scenarios' routes.

use super::route::{Route, RouteBuilder};
use super::{Scenario, SimError};

/// A scenario's route and how its drive starts and ends.
#[derive(Debug, Clone)]
pub(crate) struct ScenarioRoute {
    pub route: Route,
    /// Start at the route's speed (true) or at rest (false).
    pub start_moving: bool,
    /// Default length of the drive when no duration is given: `None` = one
    /// pass of the route (ending at its final stop, or at its end for a loop
    /// without one).
    pub default_duration_s: Option<f64>,
}

/// Build the route of `scenario`; `grade` is the `road_grade` magnitude (0 = flat).
pub(crate) fn build(scenario: Scenario, grade: f64) -> Result<ScenarioRoute, SimError> {
    match scenario {
        Scenario::Paper => Ok(ScenarioRoute {
            route: paper_course().build(scenario.name(), true, grade)?,
            start_moving: true,
            default_duration_s: None,
        }),
        Scenario::Garage => Ok(ScenarioRoute {
            route: garage().build(scenario.name(), false, grade)?,
            start_moving: false,
            default_duration_s: None,
        }),
        Scenario::Mixed => Ok(ScenarioRoute {
            route: mixed_loop().build(scenario.name(), true, grade)?,
            start_moving: false,
            default_duration_s: None,
        }),
        Scenario::Long => Ok(ScenarioRoute {
            route: mixed_loop().build(scenario.name(), true, grade)?,
            start_moving: false,
            default_duration_s: Some(3600.0),
        }),
    }
}

/// A closed course of about 2.23 km with 13 bends (radius 70-200 m), driven
/// at 60 km/h (paper section 5: CarSim's Michigan Waterford course at 60 km/h).
fn paper_course() -> RouteBuilder {
    let mut b = RouteBuilder::new(60.0);
    b.accel(1.5, 2.0)
        .straight(170.0)
        .turn(90.0, 80.0)
        .straight(140.0)
        .turn(-45.0, 100.0)
        .straight(110.0)
        .turn(100.0, 70.0)
        .free_straight(0, 80.0)
        .turn(60.0, 120.0)
        .straight(60.0)
        .turn(-20.0, 200.0)
        .turn(20.0, 200.0)
        .straight(40.0)
        .turn(-40.0, 90.0)
        .straight(80.0)
        .turn(80.0, 75.0)
        .free_straight(1, 20.0)
        .turn(70.0, 90.0)
        .straight(40.0)
        .turn(25.0, 180.0)
        .turn(-25.0, 180.0)
        .straight(30.0)
        .turn(-30.0, 150.0)
        .straight(80.0)
        .turn(75.0, 80.0)
        .straight(50.0);
    b
}

/// A parking-garage manoeuvre (the paper's Fig. 1 situation), about 540 m:
/// 40 m of street (GNSS received), then into a garage (GNSS denied from the
/// entrance on): an entrance ramp, aisles with 90 degree turns of 6 m radius,
/// a two-turn helix ramp of 9 m radius down two levels, more aisles, and
/// parking in a bay. 8-20 km/h; the heading turns through 720 degrees net.
fn garage() -> RouteBuilder {
    let mut b = RouteBuilder::new(20.0);
    b.accel(1.2, 1.5)
        .straight(40.0)
        .speed(12.0)
        .turn(-90.0, 8.0)
        .gnss_denied(true)
        .ramp(-1.0)
        .straight(18.0)
        .ramp(0.0)
        .straight(35.0)
        .turn(90.0, 6.0)
        .straight(30.0)
        .turn(90.0, 6.0)
        .straight(35.0)
        .turn(-90.0, 6.0)
        .straight(20.0)
        .speed(10.0)
        .ramp(-1.0)
        .turn(720.0, 9.0)
        .ramp(0.0)
        .speed(12.0)
        .straight(45.0)
        .turn(-90.0, 6.0)
        .straight(30.0)
        .turn(-90.0, 6.0)
        .straight(40.0)
        .turn(90.0, 6.0)
        .straight(25.0)
        .turn(90.0, 6.0)
        .straight(12.0)
        .speed(8.0)
        .turn(-90.0, 5.0)
        .straight(3.0)
        .stop(2.0);
    b
}

/// City and highway, about 9.2 km, a closed loop that turns twice through
/// 360 degrees: city blocks at 50 km/h with 10-15 m corners (traffic lights
/// and a stop sign), a full roundabout circle at 30 km/h, a highway on-ramp
/// with hard acceleration to 120 km/h, gentle highway curves (R 500-800 m),
/// a 500 m tunnel (GNSS denied), a 225 degree cloverleaf exit at 50 km/h, a
/// hard stop (6 m/s^2), a country road at 80 km/h with S-bends, and back
/// into town to stop where it started.
fn mixed_loop() -> RouteBuilder {
    let mut b = RouteBuilder::new(50.0);
    b.accel(1.8, 2.5)
        .straight(120.0)
        .stop(8.0)
        .turn(90.0, 12.0)
        .straight(200.0)
        .turn(-90.0, 10.0)
        .straight(150.0)
        .stop(3.0)
        .turn(90.0, 12.0)
        .straight(100.0)
        .speed(30.0)
        .turn(360.0, 15.0)
        .speed(50.0)
        .straight(150.0)
        .speed(45.0)
        .turn(-90.0, 40.0)
        // On-ramp: hard acceleration.
        .speed(120.0)
        .accel(3.5, 2.0)
        .straight(400.0)
        .accel(1.0, 2.0)
        .turn(20.0, 800.0)
        .straight(800.0)
        .turn(-35.0, 600.0)
        .gnss_denied(true)
        .straight(500.0)
        .gnss_denied(false)
        .straight(300.0)
        .turn(60.0, 500.0)
        .straight(200.0)
        // Cloverleaf exit, then a hard stop at the lights.
        .speed(50.0)
        .accel(1.5, 3.0)
        .turn(225.0, 50.0)
        .accel(2.0, 6.0)
        .straight(150.0)
        .stop(10.0)
        // Back through a country road with S-bends; hard acceleration away.
        .speed(50.0)
        .accel(3.0, 2.5)
        .turn(-90.0, 12.0)
        .straight(100.0)
        .speed(80.0)
        .accel(1.5, 2.0)
        .straight(300.0)
        .turn(30.0, 250.0)
        .straight(200.0)
        .turn(-30.0, 250.0)
        .free_straight(0, 500.0)
        .turn(-25.0, 300.0)
        .straight(200.0)
        .turn(25.0, 300.0)
        .straight(300.0)
        .speed(50.0)
        .accel(1.8, 2.5)
        .turn(90.0, 12.0)
        .free_straight(1, 100.0)
        .turn(90.0, 12.0)
        .straight(120.0)
        .stop(5.0);
    b
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn routes_have_their_documented_lengths() {
        let paper = build(Scenario::Paper, 0.0).unwrap().route;
        assert!((paper.length() - 2232.0).abs() < 5.0, "{}", paper.length());
        let garage = build(Scenario::Garage, 0.05).unwrap().route;
        assert!(
            (garage.length() - 542.0).abs() < 10.0,
            "{}",
            garage.length()
        );
        let mixed = build(Scenario::Mixed, 0.0).unwrap().route;
        assert!((mixed.length() - 9186.0).abs() < 10.0, "{}", mixed.length());
        assert_eq!(mixed.stops().len(), 4);
    }
}
