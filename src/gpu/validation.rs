//! The validation canary: a debug messenger that counts errors and warnings and keeps their text.
//!
//! Validation is a test oracle here, not a log: every test ends by asserting that the counts are
//! zero. The loader sends many informational "Loader Message"s through the same messenger, so only
//! warning and error severities of the validation and performance types are subscribed to. The
//! log lives behind an `Arc` that the caller may keep after the context is gone, so messages
//! emitted while the instance is destroyed (leaked objects) are still counted.
//!
//! Zero counts mean something only if the layers ran and their messages reached this log, so the
//! log records whether penumbra installed its messenger on a validated instance
//! ([`ValidationCounts::ran`]); a context without validation, or one wrapping a caller's device
//! (whose messages go to the caller's messenger), reports `ran: false`, and the test oracle and
//! the CLI refuse to call such a run clean.

use std::ffi::{c_void, CStr};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;

use ash::vk;

/// Counts and texts of the validation messages seen so far.
#[derive(Debug, Default)]
pub struct ValidationLog {
    inner: Mutex<LogInner>,
    /// Set once the validation layer is enabled and this log's messenger is installed.
    ran: AtomicBool,
}

#[derive(Debug, Default, Clone)]
struct LogInner {
    errors: u32,
    warnings: u32,
    messages: Vec<String>,
}

/// A snapshot of a [`ValidationLog`].
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct ValidationCounts {
    /// Whether the validation layers ran with this log's messenger installed. When `false` the
    /// counts are zero because nothing was counted, not because nothing was wrong.
    pub ran: bool,
    /// Messages of error severity.
    pub errors: u32,
    /// Messages of warning severity.
    pub warnings: u32,
}

/// Keeps at most this many message texts: a broken loop could otherwise log millions.
const MAX_KEPT_MESSAGES: usize = 256;

impl ValidationCounts {
    /// Validation ran and reported no error and no warning: the only state that may be called
    /// clean.
    pub fn clean(&self) -> bool {
        self.ran && self.errors == 0 && self.warnings == 0
    }
}

impl ValidationLog {
    /// The error and warning counts so far, and whether validation ran at all.
    pub fn counts(&self) -> ValidationCounts {
        let inner = self.lock();
        ValidationCounts {
            ran: self.ran(),
            errors: inner.errors,
            warnings: inner.warnings,
        }
    }

    /// Whether the validation layers ran with this log's messenger installed.
    pub fn ran(&self) -> bool {
        self.ran.load(Ordering::SeqCst)
    }

    /// Records that the layer is enabled and the messenger that feeds this log is installed.
    pub(crate) fn mark_ran(&self) {
        self.ran.store(true, Ordering::SeqCst);
    }

    /// The texts of the messages kept so far (the first 256).
    pub fn messages(&self) -> Vec<String> {
        self.lock().messages.clone()
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, LogInner> {
        // A poisoned lock only means another thread panicked while logging; the counts are
        // still meaningful, so keep going rather than propagate the panic.
        self.inner.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn record(&self, severity: vk::DebugUtilsMessageSeverityFlagsEXT, text: String) {
        let mut inner = self.lock();
        if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::ERROR) {
            inner.errors += 1;
        } else {
            inner.warnings += 1;
        }
        if inner.messages.len() < MAX_KEPT_MESSAGES {
            inner.messages.push(text);
        }
    }
}

/// The create-info for the messenger, also chained into `VkInstanceCreateInfo` so messages from
/// `vkCreateInstance`/`vkDestroyInstance` are counted too. `log` must outlive the instance.
pub(crate) fn messenger_info(log: &ValidationLog) -> vk::DebugUtilsMessengerCreateInfoEXT<'static> {
    vk::DebugUtilsMessengerCreateInfoEXT::default()
        .message_severity(
            vk::DebugUtilsMessageSeverityFlagsEXT::WARNING
                | vk::DebugUtilsMessageSeverityFlagsEXT::ERROR,
        )
        .message_type(
            vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
                | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE,
        )
        .pfn_user_callback(Some(callback))
        .user_data(log as *const ValidationLog as *mut c_void)
}

unsafe extern "system" fn callback(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    kind: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    user_data: *mut c_void,
) -> vk::Bool32 {
    if user_data.is_null() || data.is_null() {
        return vk::FALSE;
    }
    // SAFETY: user_data is the `ValidationLog` the context keeps alive until after the instance
    // is destroyed; data is valid for the duration of the callback per the spec.
    let log = unsafe { &*(user_data as *const ValidationLog) };
    let data = unsafe { &*data };
    let message = if data.p_message.is_null() {
        String::from("(no message)")
    } else {
        unsafe { CStr::from_ptr(data.p_message) }
            .to_string_lossy()
            .into_owned()
    };
    let text = format!("[{severity:?} {kind:?}] {message}");
    if std::env::var_os("PENUMBRA_PRINT_VALIDATION").is_some() {
        eprintln!("{text}");
    }
    log.record(severity, text);
    vk::FALSE
}
