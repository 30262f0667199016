//! Probe: diagnose one simulated drive with one effect switched on.
//! `cargo run --release -p calibrator --example diagnose_probe -- EFFECT|none|default SEED [VEHICLE] [SCENARIO]`
use calibrator::diagnose::{diagnose, DiagnoseConfig};
use interfaces::effects::Effect;
use simulator::{simulate, EffectSettings, Scenario, SimConfig, VehicleKind};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let which = args.first().map_or("none", |s| s.as_str());
    let seed: u64 = args.get(1).map_or(Ok(1), |s| s.parse())?;
    let vehicle = args
        .get(2)
        .map_or(Ok(VehicleKind::Saloon), |s| VehicleKind::from_name(s))?;
    let scenario = args
        .get(3)
        .map_or(Ok(Scenario::Mixed), |s| Scenario::from_name(s))?;
    let mut cfg = SimConfig::new(scenario, seed);
    cfg.vehicle = vehicle;
    cfg.effects = match which {
        "none" => EffectSettings::none(),
        "default" => EffectSettings::default(),
        id => {
            let e = Effect::from_id(id).ok_or("unknown effect")?;
            let mut s = EffectSettings::none();
            s.switch_on(e);
            if let Ok(k) = std::env::var("SCALE") {
                let (p, v) = simulator::typical_effect(e)[0];
                s.set(e, Some(p), v * k.parse::<f64>()?)?;
            }
            s
        }
    };
    let drive = simulate(&cfg)?;
    let t = std::time::Instant::now();
    let mut dc = DiagnoseConfig::default();
    if let Ok(b) = std::env::var("BLOCK_S") {
        dc.block_s = Some(b.parse()?);
    }
    let d = diagnose(&drive, &dc)?;
    eprintln!("diagnosed in {:.2} s", t.elapsed().as_secs_f64());
    println!("{}", serde_json::to_string_pretty(&d)?);
    Ok(())
}
