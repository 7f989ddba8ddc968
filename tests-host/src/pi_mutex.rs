//! A mutex with priority inheritance (POSIX `PTHREAD_PRIO_INHERIT`): while a
//! real-time thread waits for it, its holder runs at that thread's priority.
//!
//! `virtual-drive`'s frame thread (SCHED_FIFO) and application thread (normal
//! priority) share every simulated ESC ([`crate::esc_sim::SharedEsc`]). With a plain
//! mutex, an application thread preempted by other load in the middle of one PDI
//! access would keep the frame thread — and the master's frame — waiting for
//! milliseconds (priority inversion); with inheritance it finishes that access at once.
//! Relocking from the holding thread panics (error-checking mutex) instead of hanging.

use std::cell::UnsafeCell;
use std::marker::PhantomData;
use std::ops::{Deref, DerefMut};

/// A mutex with priority inheritance around a `T`.
pub struct PiMutex<T> {
    // Boxed: a pthread mutex must not move once initialised.
    raw: Box<UnsafeCell<libc::pthread_mutex_t>>,
    data: UnsafeCell<T>,
}

// SAFETY: access to `data` is serialised by the pthread mutex, as for std's Mutex.
unsafe impl<T: Send> Send for PiMutex<T> {}
// SAFETY: as above.
unsafe impl<T: Send> Sync for PiMutex<T> {}

impl<T> PiMutex<T> {
    /// A new unlocked mutex.
    pub fn new(value: T) -> Self {
        // SAFETY: zeroed storage is what pthread_mutex_init initialises; the
        // attribute object is initialised before use and destroyed after.
        let raw = unsafe {
            let raw = Box::new(UnsafeCell::new(std::mem::zeroed::<libc::pthread_mutex_t>()));
            let mut attr: libc::pthread_mutexattr_t = std::mem::zeroed();
            libc::pthread_mutexattr_init(&mut attr);
            libc::pthread_mutexattr_setprotocol(&mut attr, libc::PTHREAD_PRIO_INHERIT);
            libc::pthread_mutexattr_settype(&mut attr, libc::PTHREAD_MUTEX_ERRORCHECK);
            let rc = libc::pthread_mutex_init(raw.get(), &attr);
            libc::pthread_mutexattr_destroy(&mut attr);
            assert_eq!(rc, 0, "pthread_mutex_init");
            raw
        };
        PiMutex {
            raw,
            data: UnsafeCell::new(value),
        }
    }

    /// Waits for the mutex; it is released when the guard drops.
    pub fn lock(&self) -> PiGuard<'_, T> {
        // SAFETY: `raw` was initialised in `new` and lives as long as `self`.
        let rc = unsafe { libc::pthread_mutex_lock(self.raw.get()) };
        assert_eq!(rc, 0, "PiMutex locked twice by the same thread");
        PiGuard {
            lock: self,
            _not_send: PhantomData,
        }
    }
}

impl<T> Drop for PiMutex<T> {
    fn drop(&mut self) {
        // SAFETY: no guard can exist while `self` is dropped (guards borrow it).
        unsafe { libc::pthread_mutex_destroy(self.raw.get()) };
    }
}

/// Access to the value of a locked [`PiMutex`]; unlocks on drop (on the thread that
/// locked: the guard cannot be sent).
pub struct PiGuard<'a, T> {
    lock: &'a PiMutex<T>,
    _not_send: PhantomData<*const ()>,
}

impl<T> Deref for PiGuard<'_, T> {
    type Target = T;
    fn deref(&self) -> &T {
        // SAFETY: the guard holds the mutex.
        unsafe { &*self.lock.data.get() }
    }
}

impl<T> DerefMut for PiGuard<'_, T> {
    fn deref_mut(&mut self) -> &mut T {
        // SAFETY: the guard holds the mutex, and `&mut self` is unique.
        unsafe { &mut *self.lock.data.get() }
    }
}

impl<T> Drop for PiGuard<'_, T> {
    fn drop(&mut self) {
        // SAFETY: this thread holds the mutex (the guard is not Send).
        unsafe { libc::pthread_mutex_unlock(self.lock.raw.get()) };
    }
}
