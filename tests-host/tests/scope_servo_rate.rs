//! The scope at the servo rate on the plant: the drive (`firmware::drive`) on the plant
//! axis with the firmware's motion layer, its tick taking the servo periods' points
//! as the board's does (`tests_host::sim_drive::hand_servo_points`). A PP move
//! recorded with 0x2500:08 = 1 and divisor 1 has a sample every 100 µs: the motor
//! position moves within each millisecond, where the 1 ms tick would see one value.

use ecat_slave_stack::od::{Dictionary, ObjectKey};
use tests_host::plant::drive_tune::DriveBench;
use tests_host::sim_drive::{Axis, Motor};

fn scope_record(b: &mut DriveBench, channels: usize) -> Vec<Vec<i32>> {
    let mut bytes = Vec::new();
    let mut buf = [0u8; 512];
    for sub in 1..=6u8 {
        match Dictionary::read(&mut b.d, ObjectKey::new(0x2503, sub), &mut buf) {
            Ok(n) => bytes.extend_from_slice(&buf[..n]),
            Err(_) => break,
        }
    }
    let words: Vec<i32> = bytes
        .chunks_exact(4)
        .map(|c| i32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    words.chunks(channels).map(|c| c.to_vec()).collect()
}

#[test]
fn pp_move_recorded_every_servo_period() {
    // 0.1 rev at 5 rev/s, 500 rev/s² (50 000 units per revolution).
    let mut b = DriveBench::new(
        Motor::Ecn57_20,
        0.0,
        &[
            (0x607A, 0, &5_000i32.to_le_bytes()),
            (0x6081, 0, &250_000u32.to_le_bytes()),
            (0x6083, 0, &25_000_000u32.to_le_bytes()),
            (0x6084, 0, &25_000_000u32.to_le_bytes()),
        ],
    );
    b.enable();
    let base = b.ax.state().position;
    let ch = |i: u16, s: u8, bits: u8| u32::from(i) << 16 | u32::from(s) << 8 | u32::from(bits);
    b.write(0x2501, 0, &[0]).unwrap();
    for (k, c) in [ch(0x2510, 5, 32), ch(0x2510, 7, 16), ch(0x6041, 0, 16)]
        .into_iter()
        .enumerate()
    {
        b.write(0x2501, k as u8 + 1, &c.to_le_bytes()).unwrap();
    }
    b.write(0x2501, 0, &[3]).unwrap();
    b.write(0x2500, 8, &[1]).unwrap(); // servo period
    b.write(0x2500, 1, &1u16.to_le_bytes()).unwrap();
    b.write(0x2500, 2, &[1]).unwrap(); // trigger on the motor position
    b.write(0x2500, 3, &(base + 1000).to_le_bytes()).unwrap();
    b.write(0x2500, 4, &[1]).unwrap(); // rising
    b.write(0x2500, 5, &20u16.to_le_bytes()).unwrap();
    b.write(0x2500, 7, &[1]).unwrap(); // arm
    b.run(0x1F, 100, |_| {});
    assert_eq!(b.read_u16(0x2502, 1), 3, "done");
    let rows = scope_record(&mut b, 3);
    assert_eq!(rows.len(), 256, "768 words / 3 channels");
    // The trigger: 20 samples before it below the level, at it above.
    assert!(rows[19][0] < base + 1000 && rows[20][0] >= base + 1000);
    // 256 samples span 25.6 ms of the move: the position moves between consecutive
    // samples (a step of 100 µs at up to 5 rev/s is up to 25 units), ten values a
    // millisecond.
    let moving = rows[..120].windows(2).filter(|w| w[1][0] > w[0][0]).count();
    assert!(
        moving >= 100,
        "{moving} of 119 steps moved: {:?}",
        &rows[..30]
    );
    // The current demand accelerates the motor, and the statusword (an object, held
    // between ticks) reads Operation enabled throughout.
    assert!(rows.iter().any(|r| r[1] > 50), "current demand > 5 %");
    assert!(rows.iter().all(|r| r[2] & 0x6F == 0x27), "{:?}", rows[0]);
    // The drive asks for no more points once the record is done.
    assert!(!b.d.scope_wants_servo_points());
}
