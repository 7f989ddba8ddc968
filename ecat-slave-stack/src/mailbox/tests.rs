use super::*;

#[test]
fn mailbox_size_is_clamped_and_short_outputs_are_refused() {
    assert_eq!(MailboxServer::new(4).mailbox_size(), MIN_MAILBOX_SIZE);
    assert_eq!(MailboxServer::new(4096).mailbox_size(), MAX_MAILBOX_SIZE);
    let mut s = MailboxServer::new(64);
    s.emergency(1, 2, [3; 5]);
    let mut out = [0u8; 8];
    assert_eq!(s.next_output(&mut out, 0), 0);
    assert_eq!(s.emergencies_queued(), 1);
    for _ in 0..9 {
        s.emergency(1, 2, [3; 5]);
    }
    assert_eq!(s.emergency_overruns(), 2);
    s.set_mailbox_size(128);
    assert_eq!(s.mailbox_size(), 128);
    assert_eq!(s.emergencies_queued(), 0);
    assert_eq!(s.emergency_overruns(), 2);
}
