use super::{floor_div_i32, floor_div_i64, Scale};
use core::num::{NonZeroU32, NonZeroU64};

#[test]
fn unsigned_floor_division_is_div_euclid() {
    let xs = [
        0,
        1,
        -1,
        2,
        -2,
        49_999,
        -50_000,
        -50_001,
        i32::MAX,
        i32::MIN,
        i32::MIN + 1,
    ];
    for d in [1u32, 2, 3, 7, 4000, 50_000, 240_000, 1 << 24] {
        let nz = NonZeroU32::new(d).unwrap();
        for &x in &xs {
            assert_eq!(floor_div_i32(x, nz), x.div_euclid(d as i32), "{x} / {d}");
            let w = i64::from(x) * i64::from(d) - 1;
            let nz64 = NonZeroU64::new(u64::from(d) * 2).unwrap();
            assert_eq!(
                floor_div_i64(w, nz64),
                w.div_euclid(i64::from(d) * 2),
                "{w}"
            );
        }
    }
    let one = NonZeroU64::new(1).unwrap();
    assert_eq!(floor_div_i64(i64::MIN, one), i64::MIN);
    assert_eq!(floor_div_i64(i64::MAX, one), i64::MAX);
}

#[test]
fn narrow_and_wide_unit_conversion_agree() {
    let mut x = 0x1234_5678u32;
    for (u, c) in [
        (50_000u32, 4000u32),
        (200, 4000),
        (51_200, 240_000),
        (3, 7),
        (1, 1),
    ] {
        let s = Scale::new(u, c);
        for k in 0..20_000 {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            let p = if k < 10 {
                [0, 1, -1, i32::MAX, i32::MIN, 49_999, -50_000, 12, -13, 7][k]
            } else {
                x as i32
            };
            let (w1, f1) = s.to_counts(p);
            let (w2, f2) = s.to_counts_wide(p);
            assert_eq!(w1, w2, "{u}/{c} p {p}");
            assert!((f1 - f2).abs() < 1e-6, "{u}/{c} p {p}");
            assert!((0.0..1.0).contains(&f1));
            // Round trip within half a unit.
            let back = s.to_units(w1);
            let (su, sc) = (i64::from(s.units.get()), i64::from(s.counts.get()));
            if su >= sc && p.unsigned_abs() < (1 << 28) {
                assert!(
                    (i64::from(back) - i64::from(p)).abs() * sc <= su,
                    "{u}/{c} p {p} back {back}"
                );
            }
        }
    }
}
