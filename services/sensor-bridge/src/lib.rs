//! Sensor bridge: drives in and out (drive folder, MCAP), the vehicle
//! simulator, and publishing drives over iceoryx2.
