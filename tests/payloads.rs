//! The units' own `same_bits` overrides (the data-contract records in
//! `units::tm`, the L1's cache line) answer what comparing the packings would,
//! as the kernel's overrides do (`rtl::bits`' tests): a link monitor that asks
//! `same_bits` of a repeated offer must see +0/-0 differ and a NaN equal itself.

use dualstream::contract::{HitRec, RayRec};
use dualstream::rtl::Payload;
use dualstream::rtl::bits::packed;
use dualstream::units::l1::Line;
use glam::Vec3;

fn check<T: Payload>(pairs: &[(T, T)]) {
    for (a, b) in pairs {
        let packed_equal = packed(a) == packed(b);
        assert_eq!(a.same_bits(b), packed_equal, "{a:?} vs {b:?}");
        assert!(a.same_bits(a), "{a:?} vs itself");
    }
}

const NAN: f32 = f32::from_bits(0x7fc0_0001);

#[test]
fn hit_record_same_bits_is_equality_of_the_packings() {
    let hit = |t: f32| HitRec {
        t,
        tri_id: 3,
        u: 0.25,
        v: 0.5,
    };
    check(&[
        (hit(0.0), hit(-0.0)),
        (hit(NAN), hit(NAN)),
        (hit(1.0), hit(1.0)),
        (
            hit(1.0),
            HitRec {
                tri_id: 4,
                ..hit(1.0)
            },
        ),
    ]);
}

#[test]
fn ray_record_same_bits_is_equality_of_the_packings() {
    let ray = |x: f32| RayRec {
        origin: Vec3::new(x, 1.0, 2.0),
        dir: Vec3::new(0.0, 0.0, 1.0),
        ray_id: 7,
        entry: 9,
    };
    check(&[
        (ray(0.0), ray(-0.0)),
        (ray(NAN), ray(NAN)),
        (
            ray(1.0),
            RayRec {
                entry: 8,
                ..ray(1.0)
            },
        ),
        (
            ray(1.0),
            RayRec {
                ray_id: 1 << 31 | 7,
                ..ray(1.0)
            },
        ),
    ]);
}

#[test]
fn line_same_bits_is_equality_of_the_packings() {
    let mut l = Line::default();
    l.0[63] = 1;
    check(&[(l.clone(), Line::default()), (l.clone(), l)]);
}
