//! Lat/lon to metres as Lanelet2's `UtmProjector` does it: the universal transverse Mercator
//! projection on the WGS84 ellipsoid (GeographicLib's `UTMUPS::Forward`), every point in the
//! zone of the origin (Lanelet2 transfers points of neighbouring zones into the origin's), the
//! origin's own coordinates subtracted. cpmx puts the origin at the south-west corner of the
//! map's nodes, so its coordinates are Lanelet2's loaded with `UtmProjector(Origin(lat_min,
//! lon_min))`.
//!
//! The transverse Mercator is evaluated with Krüger's series to sixth order in the third
//! flattening, as GeographicLib's `TransverseMercator` is: it agrees with GeographicLib to
//! well under a millimetre within a zone and its neighbours.

/// WGS84 equatorial radius [m].
pub const WGS84_A_M: f64 = 6_378_137.0;
/// WGS84 flattening.
pub const WGS84_F: f64 = 1.0 / 298.257_223_563;
/// UTM's central scale factor.
pub const UTM_K0: f64 = 0.9996;

/// A point outside the latitudes UTM covers (80° S to 84° N; beyond them GeographicLib
/// switches to the polar stereographic projection, which cpmx does not implement).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OutsideUtm {
    /// The latitude that was given [deg].
    pub lat_deg: f64,
}

/// The UTM projection of one zone, with an origin subtracted.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UtmProjector {
    /// The zone every point is projected in (1..=60).
    pub zone: u8,
    central_meridian_deg: f64,
    origin_m: [f64; 2],
}

impl UtmProjector {
    /// The projector of `origin`'s standard zone, with `origin` at `(0, 0)`.
    pub fn new(origin_lat_deg: f64, origin_lon_deg: f64) -> Result<Self, OutsideUtm> {
        let zone = standard_zone(origin_lat_deg, origin_lon_deg)?;
        let central_meridian_deg = 6.0 * f64::from(zone) - 183.0;
        let origin_m = transverse_mercator(origin_lat_deg, origin_lon_deg - central_meridian_deg);
        Ok(Self {
            zone,
            central_meridian_deg,
            origin_m,
        })
    }

    /// `(x, y)` of a point [m]: x east, y north, relative to the origin.
    pub fn forward(&self, lat_deg: f64, lon_deg: f64) -> Result<[f64; 2], OutsideUtm> {
        if !(-80.0..84.0).contains(&lat_deg) {
            return Err(OutsideUtm { lat_deg });
        }
        let [x, y] = transverse_mercator(lat_deg, lon_deg - self.central_meridian_deg);
        Ok([x - self.origin_m[0], y - self.origin_m[1]])
    }
}

/// GeographicLib's `UTMUPS::StandardZone` for the UTM latitudes, with the Norway and Svalbard
/// exceptions.
fn standard_zone(lat_deg: f64, lon_deg: f64) -> Result<u8, OutsideUtm> {
    if !(-80.0..84.0).contains(&lat_deg) || !lon_deg.is_finite() {
        return Err(OutsideUtm { lat_deg });
    }
    // Longitude in [-180, 180).
    let lon = (lon_deg + 180.0).rem_euclid(360.0) - 180.0;
    let ilon = lon.floor() as i32;
    let mut zone = (ilon + 186) / 6;
    // Latitude band: 8° bands from C (index -10) at 80° S to X (index 9), 12° high.
    let band = ((lat_deg.floor() as i32 + 80) / 8 - 10).clamp(-10, 9);
    if band == 7 && zone == 31 && ilon >= 3 {
        zone = 32;
    } else if band == 9 && (0..42).contains(&ilon) {
        zone = 2 * ((ilon + 183) / 12) + 1;
    }
    Ok(u8::try_from(zone.clamp(1, 60)).unwrap_or(1))
}

/// Unscaled-origin transverse Mercator with UTM's scale factor: easting and northing [m] of a
/// point `dlon_deg` east of the central meridian, without false easting or northing.
fn transverse_mercator(lat_deg: f64, dlon_deg: f64) -> [f64; 2] {
    let f = WGS84_F;
    let e = (f * (2.0 - f)).sqrt();
    let n = f / (2.0 - f);
    let (n2, n3) = (n * n, n * n * n);
    let (n4, n5, n6) = (n2 * n2, n2 * n3, n3 * n3);
    // Rectifying radius and Krüger's alpha coefficients.
    let a_rect = WGS84_A_M / (1.0 + n) * (1.0 + n2 / 4.0 + n4 / 64.0 + n6 / 256.0);
    let alpha = [
        n / 2.0 - 2.0 * n2 / 3.0 + 5.0 * n3 / 16.0 + 41.0 * n4 / 180.0 - 127.0 * n5 / 288.0
            + 7891.0 * n6 / 37800.0,
        13.0 * n2 / 48.0 - 3.0 * n3 / 5.0 + 557.0 * n4 / 1440.0 + 281.0 * n5 / 630.0
            - 1_983_433.0 * n6 / 1_935_360.0,
        61.0 * n3 / 240.0 - 103.0 * n4 / 140.0 + 15061.0 * n5 / 26880.0 + 167_603.0 * n6 / 181_440.0,
        49561.0 * n4 / 161_280.0 - 179.0 * n5 / 168.0 + 6_601_661.0 * n6 / 7_257_600.0,
        34729.0 * n5 / 80640.0 - 3_418_889.0 * n6 / 1_995_840.0,
        212_378_941.0 * n6 / 319_334_400.0,
    ];
    // Conformal latitude, then the Gauss-Schreiber coordinates.
    let (phi, lambda) = (lat_deg.to_radians(), dlon_deg.to_radians());
    let sin_phi = phi.sin();
    let t = (sin_phi.atanh() - e * (e * sin_phi).atanh()).sinh();
    let xi = t.atan2(lambda.cos());
    let eta = (lambda.sin() / (t * t + lambda.cos().powi(2)).sqrt()).asinh();
    let (mut x, mut y) = (eta, xi);
    for (j, a) in alpha.iter().enumerate() {
        let k = 2.0 * (j as f64 + 1.0);
        x += a * (k * xi).cos() * (k * eta).sinh();
        y += a * (k * xi).sin() * (k * eta).cosh();
    }
    [UTM_K0 * a_rect * x, UTM_K0 * a_rect * y]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// UTM coordinates of points in both hemispheres and in the Norway and Svalbard zones, as
    /// lanelet2 1.2.3's `UtmProjector` (GeographicLib) gives them without an offset.
    #[test]
    fn agrees_with_lanelet2s_projector_on_known_points() {
        // (lat, lon, zone, easting, northing)
        let cases = [
            (49.013_777_8, 8.404_444_4, 32, 456_451.684_8, 5_429_158.247_2),
            (0.0, 9.0, 32, 500_000.0, 0.0),
            (35.2265, 138.8033, 54, 300_084.895_4, 3_900_372.692_7),
            (-33.9, -70.6, 19, 352_063.226_2, 6_247_779.483_1),
            (60.0, 4.0, 32, 221_288.770_2, 6_661_953.040_5),
            (78.0, 15.0, 33, 500_000.0, 8_658_369.585_8),
        ];
        for (lat, lon, zone, e, n) in cases {
            assert_eq!(standard_zone(lat, lon), Ok(zone));
            let [x, y] = transverse_mercator(lat, lon - (6.0 * f64::from(zone) - 183.0));
            let false_northing = if lat < 0.0 { 10_000_000.0 } else { 0.0 };
            assert!(
                (x + 500_000.0 - e).abs() < 1e-4,
                "{lat} {lon}: easting {}",
                x + 500_000.0
            );
            assert!((y + false_northing - n).abs() < 1e-4, "{lat} {lon}: northing {y}");
        }
    }

    /// Points relative to an origin, one of them in the next zone west (Lanelet2 transfers it
    /// into the origin's zone), as lanelet2's `UtmProjector(Origin(49, 8.4))` gives them.
    #[test]
    fn points_are_relative_to_the_origin_in_its_zone() {
        let p = UtmProjector::new(49.0, 8.4).expect("in UTM");
        assert_eq!(p.forward(49.0, 8.4), Ok([0.0, 0.0]));
        for (lat, lon, x_m, y_m) in [
            (49.001, 8.4003, 22.820_757, 110.991_042),
            (48.99, 5.9, -182_886.537_086, 3_346.306_535),
        ] {
            let [x, y] = p.forward(lat, lon).expect("in UTM");
            assert!((x - x_m).abs() < 1e-5 && (y - y_m).abs() < 1e-5, "{x} {y}");
        }
    }

    #[test]
    fn zones_follow_geographiclib_including_the_exceptions() {
        assert_eq!(standard_zone(49.0, 8.4), Ok(32));
        assert_eq!(standard_zone(35.2, 138.8), Ok(54));
        assert_eq!(standard_zone(60.0, 4.0), Ok(32)); // south-western Norway
        assert_eq!(standard_zone(78.0, 15.0), Ok(33)); // Svalbard
        assert_eq!(standard_zone(-33.9, -70.6), Ok(19));
        assert_eq!(standard_zone(0.0, 180.0), Ok(1));
        assert!(standard_zone(85.0, 0.0).is_err());
    }
}
