//! One simulated ATmega328P: the only place of the project that calls simavr's C API.
//!
//! # How it works
//!
//! * The core is made with `avr_make_mcu_by_name("atmega328p")` and `avr_init`, then the ELF is
//!   read with simavr's own loader (`elf_read_firmware` + `avr_load_firmware`, which also gives us
//!   the symbol table for stack painting).
//! * simavr's default `sleep` callback `usleep`s to keep simulated time in step with the wall
//!   clock; it is replaced by a no-op, so a sleeping core jumps straight to its next cycle timer.
//!   [`Avr::run_until`] registers a cycle timer at its target, so such a jump never passes the
//!   target (it may end one cycle after it: simavr adds `1 + sleep`).
//! * UART0's "poll sleep" (`usleep(1)` on every idle `UCSR0A` read) and "stdio" (print lines on
//!   stdout) flags are cleared.
//! * `avr->run_cycle_limit` is raised so that `avr_run` executes straight-line code in batches up
//!   to the next cycle timer or interrupt instead of returning after every instruction: timers are
//!   still processed at the right cycle, only the per-call overhead goes.
//! * UART output comes from a notify hook on `UART_IRQ_OUTPUT` (cycle-stamped when the firmware
//!   writes `UDR0`); UART input is queued here and raised on `UART_IRQ_INPUT` by our own cycle
//!   timer, one byte per byte time of the UART as simavr computes it (`cycles_per_byte` of the
//!   `avr_uart_t`). simavr's xon/xoff IRQs are not used for pacing: XON is raised on every idle
//!   read of `UCSR0A`, and a per-byte timer gives the same bytes at the same cycles every run.
//! * simavr's `avr_reset` (watchdog reset) sets `avr->cycle` back to 0 and drops every cycle
//!   timer; [`Avr`] keeps a monotonic cycle count across resets and re-arms its timers.
//!
//! # Threads
//!
//! Every piece of simavr state this crate touches lives in the `avr_t` allocation (a copy of a
//! `const` core template), its IO modules and IRQ pool. The process-wide state of simavr is the
//! global logger pointer (never changed here, only read when logging; the default logger is a
//! `vfprintf` to stdout/stderr, which is thread-safe) and `donttrace` in `sim_core.c` (only used
//! when tracing is on, which it never is here). libelf's `elf_version` is idempotent. So one
//! [`Avr`] may be moved to another thread: it is `Send` (not `Sync`: all access goes through
//! `&mut self` or the owning thread). The tests run instances in parallel threads.

use std::collections::{HashMap, VecDeque};
use std::ffi::{c_void, CStr, CString};
use std::fmt;
use std::os::raw::c_int;
use std::path::{Path, PathBuf};
use std::ptr::{self, NonNull};

use simavr_ffi as ffi;

/// CPU clock of the Uno.
pub const F_CPU: u32 = 16_000_000;

/// Byte written over free SRAM before boot to measure the stack peak.
pub const STACK_PAINT: u8 = 0xA5;

/// `AVR_IOCTL_DEF` of simavr's `sim_io.h` (a C macro, so not in the bindings).
const fn ioctl_def(a: u8, b: u8, c: u8, d: u8) -> u32 {
    ((a as u32) << 24) | ((b as u32) << 16) | ((c as u32) << 8) | d as u32
}
const IOCTL_UART0_GETIRQ: u32 = ioctl_def(b'u', b'a', b'r', b'0');
const IOCTL_UART0_SET_FLAGS: u32 = ioctl_def(b'u', b'a', b's', b'0');
const IOCTL_EEPROM_GET: u32 = ioctl_def(b'e', b'e', b'g', b'p');
const IOCTL_EEPROM_SET: u32 = ioctl_def(b'e', b'e', b's', b'p');

/// ATmega328P `UCSR0B` data address and its `RXEN0` bit.
const UCSR0B: usize = 0xC1;
const RXEN0: u8 = 1 << 4;
/// Instructions `avr_run` may execute per call before returning (bounded by the next timer).
const RUN_CYCLE_LIMIT: u64 = 4096;

/// Ms ↔ cycles at [`F_CPU`].
pub fn ms_to_cycles(ms: f64) -> u64 {
    (ms * (F_CPU as f64 / 1000.0)).round().max(0.0) as u64
}

/// Cycles → ms at [`F_CPU`].
pub fn cycles_to_ms(cycles: u64) -> f64 {
    cycles as f64 * 1000.0 / F_CPU as f64
}

/// What the simulated core is doing.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum State {
    /// Executing instructions.
    Running,
    /// In SLEEP, waiting for an interrupt; simulated time keeps advancing.
    Sleeping,
    /// Stopped for good: SLEEP with interrupts disabled (simavr's "done").
    Done,
    /// Crashed: invalid opcode, bad memory access, etc.
    Crashed,
    /// Any other simavr state (stopped, limbo, gdb stepping): not expected here.
    Other(i32),
}

impl State {
    fn from_raw(s: c_int) -> State {
        match s as u32 {
            ffi::cpu_Running => State::Running,
            ffi::cpu_Sleeping => State::Sleeping,
            ffi::cpu_Done => State::Done,
            ffi::cpu_Crashed => State::Crashed,
            _ => State::Other(s),
        }
    }

    /// True while the firmware can still make progress (running or sleeping).
    pub fn is_alive(self) -> bool {
        matches!(self, State::Running | State::Sleeping)
    }
}

/// Why an [`Avr`] could not be made or an access failed.
#[derive(Debug)]
pub enum Error {
    /// The firmware file could not be read.
    Io(PathBuf, std::io::Error),
    /// simavr could not parse the ELF.
    Elf(PathBuf),
    /// The file is not a whole AVR ELF ([`crate::elf::inspect`]).
    BadElf(PathBuf, crate::elf::ElfProblem),
    /// simavr does not know the MCU (should not happen).
    Mcu,
    /// The firmware has no UART0 (should not happen on an ATmega328P).
    NoUart,
    /// An EEPROM or SRAM access out of range.
    OutOfRange {
        /// Which memory.
        what: &'static str,
        /// First address.
        addr: usize,
        /// Length.
        len: usize,
        /// Size of the memory.
        size: usize,
    },
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Io(p, e) => write!(f, "cannot read firmware {}: {e}", p.display()),
            Error::Elf(p) => write!(f, "simavr cannot load ELF {}", p.display()),
            Error::BadElf(p, problem) => write!(f, "{}: {problem}", p.display()),
            Error::Mcu => f.write_str("simavr does not know atmega328p"),
            Error::NoUart => f.write_str("simavr core has no UART0"),
            Error::OutOfRange {
                what,
                addr,
                len,
                size,
            } => write!(f, "{what} access {addr:#x}+{len} outside 0..{size:#x}"),
        }
    }
}

impl std::error::Error for Error {}

/// A byte on the UART with the (monotonic) cycle at which it was sent: for output, the cycle the
/// firmware wrote `UDR0` (the start bit); for input, the cycle it was raised on the RX line
/// (simavr sets `RXC0` one byte time later).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct UartByte {
    /// Monotonic cycle count.
    pub cycle: u64,
    /// The byte.
    pub byte: u8,
}

impl UartByte {
    /// [`UartByte::cycle`] in ms.
    pub fn ms(&self) -> f64 {
        cycles_to_ms(self.cycle)
    }
}

/// State shared with the C callbacks. It lives in a `Box` turned into a raw pointer, so the
/// callbacks may mutate it through that pointer while Rust code holds no reference to it (Rust
/// code only dereferences it between calls into simavr).
struct Shared {
    avr: *mut ffi::avr_t,
    uart: *mut ffi::avr_uart_t,
    uart_in: *mut ffi::avr_irq_t,
    /// Added to `avr->cycle` to make the monotonic count (grows on each simavr reset).
    base: u64,
    tx: Vec<UartByte>,
    /// Bytes to inject, each with the earliest monotonic cycle it may start.
    rx_queue: VecDeque<(u64, u8)>,
    rx_armed: bool,
    /// Monotonic cycle at which the RX line is free again.
    rx_line_free: u64,
    rx_log: Vec<UartByte>,
    rx_dropped: u64,
}

impl Shared {
    fn now(&self) -> u64 {
        // SAFETY: `avr` is valid for the life of the `Avr` owning this `Shared`.
        self.base + unsafe { (*self.avr).cycle }
    }

    fn cycles_per_byte(&self) -> u64 {
        // SAFETY: `uart` points into the live `avr_t`'s IO module list.
        unsafe { (*self.uart).cycles_per_byte }.max(1)
    }

    /// Arms the RX timer for the queue head if it is not armed.
    ///
    /// # Safety
    /// `this` must be the live `Shared` of a live core; no Rust reference to it may be held.
    unsafe fn arm_rx(this: *mut Shared) {
        let s = &mut *this;
        if s.rx_armed {
            return;
        }
        let Some(&(not_before, _)) = s.rx_queue.front() else {
            return;
        };
        let now = s.now();
        let at = not_before.max(s.rx_line_free).max(now);
        s.rx_armed = true;
        ffi::avr_cycle_timer_register(s.avr, at - now, Some(rx_timer), this.cast());
    }
}

/// Cycle timer: raises the next queued byte on UART0's input IRQ and re-arms itself for the
/// following byte one byte time later (or at its requested start).
unsafe extern "C" fn rx_timer(
    _avr: *mut ffi::avr_t,
    when: ffi::avr_cycle_count_t,
    param: *mut c_void,
) -> ffi::avr_cycle_count_t {
    let this = param.cast::<Shared>();
    // SAFETY: `param` is the `Shared` registered with this timer; it outlives the core.
    let (irq, byte, rxen) = {
        let s = &mut *this;
        let Some((_, byte)) = s.rx_queue.pop_front() else {
            s.rx_armed = false;
            return 0;
        };
        let cycle = s.base + when;
        let rxen = *(*s.avr).data.add(UCSR0B) & RXEN0 != 0;
        if rxen {
            s.rx_log.push(UartByte { cycle, byte });
        } else {
            // simavr drops input while the receiver is off, as the hardware does.
            s.rx_dropped += 1;
        }
        s.rx_line_free = cycle + s.cycles_per_byte();
        (s.uart_in, byte, rxen)
    };
    if rxen {
        ffi::avr_raise_irq(irq, byte as u32);
    }
    let s = &mut *this;
    match s.rx_queue.front() {
        Some(&(not_before, _)) => {
            // Absolute simavr cycle of the next byte; always > `when`.
            let at = not_before.max(s.rx_line_free);
            at.saturating_sub(s.base).max(when + 1)
        }
        None => {
            s.rx_armed = false;
            0
        }
    }
}

/// IRQ hook on UART0 output: records the byte with its cycle.
unsafe extern "C" fn tx_notify(_irq: *mut ffi::avr_irq_t, value: u32, param: *mut c_void) {
    // SAFETY: `param` is the `Shared` registered with this hook; it outlives the core.
    let s = &mut *param.cast::<Shared>();
    let cycle = s.now();
    s.tx.push(UartByte {
        cycle,
        byte: value as u8,
    });
}

/// Marks the end of a `run_until` so a sleeping core does not jump past it.
unsafe extern "C" fn target_timer(
    _avr: *mut ffi::avr_t,
    _when: ffi::avr_cycle_count_t,
    _param: *mut c_void,
) -> ffi::avr_cycle_count_t {
    0
}

/// Replaces simavr's wall-clock-syncing sleep: simulated time only.
unsafe extern "C" fn no_sleep(_avr: *mut ffi::avr_t, _how_long: ffi::avr_cycle_count_t) {}

extern "C" {
    fn free(p: *mut c_void);
}

/// Installs (once per process) a logger that drops simavr's chatter: messages logged without a
/// core (`avr == NULL`, e.g. the ELF loader's "Loaded N bytes…" debug lines, which simavr's
/// default logger prints whatever the level) are kept only at error level; messages of a core
/// follow that core's level, as with simavr's own logger. x86_64 only, where the bindings give `va_list` as a
/// pointer that can be handed on to `vfprintf`; elsewhere simavr's default logger stays.
fn install_logger() {
    #[cfg(target_arch = "x86_64")]
    {
        use std::os::raw::c_char;
        use std::sync::Once;
        extern "C" {
            fn vfprintf(
                stream: *mut c_void,
                fmt: *const c_char,
                ap: *mut ffi::__va_list_tag,
            ) -> c_int;
            static stderr: *mut c_void;
        }
        unsafe extern "C" fn logger(
            avr: *mut ffi::avr_t,
            level: c_int,
            fmt: *const c_char,
            ap: *mut ffi::__va_list_tag,
        ) {
            // SAFETY: `avr` is null or the live core that logs; `fmt`/`ap` come from simavr.
            let limit = if avr.is_null() {
                ffi::LOG_ERROR as c_int
            } else {
                (*avr).log() as c_int
            };
            if level <= limit {
                vfprintf(stderr, fmt, ap);
            }
        }
        static ONCE: Once = Once::new();
        // SAFETY: sets simavr's global logger pointer once, before this process makes a core
        // through this crate; `logger` has exactly the `avr_logger_p` signature.
        ONCE.call_once(|| unsafe { ffi::avr_global_logger_set(Some(logger)) });
    }
}

/// One simulated ATmega328P at 16 MHz running a firmware ELF.
pub struct Avr {
    avr: NonNull<ffi::avr_t>,
    shared: NonNull<Shared>,
    symbols: HashMap<String, u32>,
    /// Painted SRAM range `[start, end]` (data addresses), if the ELF told where static data ends.
    paint: Option<(usize, usize)>,
    path: PathBuf,
}

// SAFETY: see the module docs: all simavr state reachable from an `Avr` is owned by it (no
// thread-local or shared mutable globals are used), and the raw pointers are never shared with
// another `Avr`.
unsafe impl Send for Avr {}

impl fmt::Debug for Avr {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Avr")
            .field("firmware", &self.path)
            .field("cycle", &self.cycle())
            .field("state", &self.state())
            .finish()
    }
}

impl Avr {
    /// Loads `firmware` (an AVR ELF) into a fresh ATmega328P at [`F_CPU`], paints free SRAM for
    /// [`Avr::stack_peak`], and leaves it at cycle 0, ready to run.
    ///
    /// simavr's ELF loader also writes the ELF's `.eeprom` section into the EEPROM (the rest
    /// reads 0xFF, erased), as `avrdude -U eeprom:w:fw.elf:e` would on a board: the hoploc
    /// firmwares carry their built-in config there. To model a board flashed through the
    /// bootloader (EEPROM never written), erase it with [`Avr::eeprom_write`] before running.
    pub fn load(firmware: impl AsRef<Path>) -> Result<Avr, Error> {
        install_logger();
        let path = firmware.as_ref().to_path_buf();
        // simavr's loader ends the process on a truncated file: check the file first.
        crate::elf::inspect(&path)?;
        let cpath = CString::new(path.as_os_str().as_encoded_bytes())
            .map_err(|_| Error::Elf(path.clone()))?;

        // SAFETY: plain FFI calls with valid arguments; every pointer simavr returns is checked
        // before use, and `fw` is zero-initialised as `elf_read_firmware` requires.
        unsafe {
            let mut fw: Box<ffi::elf_firmware_t> = Box::new(std::mem::zeroed());
            if ffi::elf_read_firmware(cpath.as_ptr(), &mut *fw) != 0 {
                return Err(Error::Elf(path));
            }
            let symbols = take_symbols(&mut fw);

            let avr = ffi::avr_make_mcu_by_name(c"atmega328p".as_ptr());
            let Some(avr) = NonNull::new(avr) else {
                return Err(Error::Mcu);
            };
            let a = avr.as_ptr();
            ffi::avr_init(a);
            (*a).frequency = F_CPU;
            (*a).sleep = Some(no_sleep);
            (*a).run_cycle_limit = RUN_CYCLE_LIMIT;
            fw.frequency = F_CPU;
            ffi::avr_load_firmware(a, &mut *fw);

            let uart = find_uart0(a);
            let uart_irq = ffi::avr_io_getirq(a, IOCTL_UART0_GETIRQ, 0);
            if uart.is_null() || uart_irq.is_null() {
                ffi::avr_terminate(a);
                free(a.cast());
                return Err(Error::NoUart);
            }
            let mut flags: u32 = 0;
            ffi::avr_ioctl(a, IOCTL_UART0_SET_FLAGS, (&mut flags as *mut u32).cast());

            let shared = NonNull::from(Box::leak(Box::new(Shared {
                avr: a,
                uart,
                uart_in: uart_irq.add(ffi::UART_IRQ_INPUT as usize),
                base: 0,
                tx: Vec::new(),
                rx_queue: VecDeque::new(),
                rx_armed: false,
                rx_line_free: 0,
                rx_log: Vec::new(),
                rx_dropped: 0,
            })));
            ffi::avr_irq_register_notify(
                uart_irq.add(ffi::UART_IRQ_OUTPUT as usize),
                Some(tx_notify),
                shared.as_ptr().cast(),
            );

            let mut me = Avr {
                avr,
                shared,
                symbols,
                paint: None,
                path,
            };
            me.paint_stack();
            Ok(me)
        }
    }

    fn raw(&self) -> *mut ffi::avr_t {
        self.avr.as_ptr()
    }

    fn sh(&self) -> &Shared {
        // SAFETY: no simavr call is running while `&self` is borrowed, so no callback mutates it.
        unsafe { self.shared.as_ref() }
    }

    fn sh_mut(&mut self) -> &mut Shared {
        // SAFETY: as `sh`, with `&mut self` excluding every other access.
        unsafe { self.shared.as_mut() }
    }

    /// The firmware path.
    pub fn firmware(&self) -> &Path {
        &self.path
    }

    /// Monotonic cycle count since load (kept across watchdog resets, which simavr counts from 0).
    pub fn cycle(&self) -> u64 {
        self.sh().now()
    }

    /// [`Avr::cycle`] in ms.
    pub fn time_ms(&self) -> f64 {
        cycles_to_ms(self.cycle())
    }

    /// The core's state.
    pub fn state(&self) -> State {
        // SAFETY: reading a field of the live core.
        State::from_raw(unsafe { (*self.raw()).state })
    }

    /// Runs until the monotonic cycle count reaches `target` (it may pass it by the length of
    /// one instruction, or one cycle after a sleep) or the core stops (done or crashed; the
    /// count then stays where the core stopped). Returns the state.
    pub fn run_until(&mut self, target: u64) -> State {
        let a = self.raw();
        let sh = self.shared.as_ptr();
        let mut state = self.state();
        // SAFETY: FFI calls on the live core; `Shared` is only touched through `sh` between them.
        unsafe {
            if (*sh).now() >= target || !state.is_alive() {
                return state;
            }
            let arm_target = |sh: *mut Shared| {
                let rel = target - (*sh).now();
                ffi::avr_cycle_timer_register(a, rel, Some(target_timer), sh.cast());
            };
            arm_target(sh);
            Shared::arm_rx(sh);
            loop {
                let before = (*a).cycle;
                state = State::from_raw(ffi::avr_run(a));
                if (*a).cycle < before {
                    // simavr reset the core (watchdog): cycle restarted at 0, timers dropped.
                    (*sh).base += before;
                    (*sh).rx_armed = false;
                    (*sh).rx_line_free = (*sh).rx_line_free.min((*sh).now());
                    if (*sh).now() < target {
                        arm_target(sh);
                    }
                    Shared::arm_rx(sh);
                }
                if !state.is_alive() || (*sh).now() >= target {
                    break;
                }
            }
            ffi::avr_cycle_timer_cancel(a, Some(target_timer), sh.cast());
        }
        state
    }

    /// Runs for `cycles` more cycles (see [`Avr::run_until`]).
    pub fn run_for(&mut self, cycles: u64) -> State {
        let target = self.cycle() + cycles;
        self.run_until(target)
    }

    /// Runs for `ms` more milliseconds of simulated time.
    pub fn run_for_ms(&mut self, ms: f64) -> State {
        self.run_for(ms_to_cycles(ms))
    }

    // ---- UART0 ----

    /// Cycles per byte of UART0 as simavr paces it: 11 bit times per 8N1 byte (simavr counts a
    /// parity bit even when parity is off), computed when the firmware writes `UBRR0` (so set
    /// `U2X0` first). 3080 at 57600 baud with U2X (`UBRR0` = 34); simavr's default before any
    /// `UBRR0` write is 100 µs.
    pub fn uart_cycles_per_byte(&self) -> u64 {
        self.sh().cycles_per_byte()
    }

    /// Queues `bytes` for UART0's RX line, starting now (or when the bytes queued before them
    /// are through), one byte per [`Avr::uart_cycles_per_byte`]. Bytes that reach the line while
    /// the receiver is off (`RXEN0` clear) are dropped, as simavr and the hardware do.
    pub fn uart_send(&mut self, bytes: &[u8]) {
        let now = self.cycle();
        self.uart_send_at(now, bytes);
    }

    /// As [`Avr::uart_send`], but the first byte starts no earlier than monotonic cycle `cycle`.
    /// Bytes go out in the order they were queued.
    pub fn uart_send_at(&mut self, cycle: u64, bytes: &[u8]) {
        self.sh_mut()
            .rx_queue
            .extend(bytes.iter().map(|&b| (cycle, b)));
        // SAFETY: live core and `Shared`; no reference to `Shared` is held across the call.
        unsafe { Shared::arm_rx(self.shared.as_ptr()) };
    }

    /// Input bytes still queued (not yet on the RX line).
    pub fn uart_rx_pending(&self) -> usize {
        self.sh().rx_queue.len()
    }

    /// Input bytes put on the RX line so far, with their cycles.
    pub fn uart_input(&self) -> &[UartByte] {
        &self.sh().rx_log
    }

    /// Input bytes dropped because the receiver was off.
    pub fn uart_rx_dropped(&self) -> u64 {
        self.sh().rx_dropped
    }

    /// Every byte the firmware wrote to UART0 so far (unless taken), with its cycle.
    pub fn uart_output(&self) -> &[UartByte] {
        &self.sh().tx
    }

    /// Takes the output collected so far.
    pub fn take_uart_output(&mut self) -> Vec<UartByte> {
        std::mem::take(&mut self.sh_mut().tx)
    }

    /// The output collected so far as text (lossy UTF-8).
    pub fn uart_output_string(&self) -> String {
        let bytes: Vec<u8> = self.sh().tx.iter().map(|b| b.byte).collect();
        String::from_utf8_lossy(&bytes).into_owned()
    }

    // ---- EEPROM ----

    /// EEPROM size in bytes (1024).
    pub fn eeprom_size(&self) -> usize {
        // SAFETY: reading a field of the live core.
        unsafe { (*self.raw()).e2end as usize + 1 }
    }

    /// Writes `data` into EEPROM at `offset` (before boot: a preload the firmware will see).
    pub fn eeprom_write(&mut self, offset: usize, data: &[u8]) -> Result<(), Error> {
        self.eeprom_check(offset, data.len())?;
        if data.is_empty() {
            return Ok(());
        }
        let mut desc = ffi::avr_eeprom_desc_t {
            ee: data.as_ptr().cast_mut(),
            offset: offset as u16,
            size: data.len() as u32,
        };
        // SAFETY: EEPROM_SET only reads `size` bytes from `ee` (checked in range above).
        let r = unsafe {
            ffi::avr_ioctl(
                self.raw(),
                IOCTL_EEPROM_SET,
                (&mut desc as *mut ffi::avr_eeprom_desc_t).cast(),
            )
        };
        debug_assert_eq!(r, 0);
        Ok(())
    }

    /// Reads `len` EEPROM bytes at `offset`.
    pub fn eeprom_read(&self, offset: usize, len: usize) -> Result<Vec<u8>, Error> {
        self.eeprom_check(offset, len)?;
        let mut out = vec![0u8; len];
        let mut desc = ffi::avr_eeprom_desc_t {
            ee: out.as_mut_ptr(),
            offset: offset as u16,
            size: len as u32,
        };
        // SAFETY: EEPROM_GET copies `size` bytes into `ee`, which has room for them.
        let r = unsafe {
            ffi::avr_ioctl(
                self.raw(),
                IOCTL_EEPROM_GET,
                (&mut desc as *mut ffi::avr_eeprom_desc_t).cast(),
            )
        };
        debug_assert_eq!(r, 0);
        Ok(out)
    }

    fn eeprom_check(&self, addr: usize, len: usize) -> Result<(), Error> {
        let size = self.eeprom_size();
        if addr.checked_add(len).is_none_or(|e| e > size) {
            return Err(Error::OutOfRange {
                what: "EEPROM",
                addr,
                len,
                size,
            });
        }
        Ok(())
    }

    // ---- SRAM and symbols ----

    /// RAMEND (0x8FF).
    pub fn ramend(&self) -> usize {
        // SAFETY: reading a field of the live core.
        unsafe { (*self.raw()).ramend as usize }
    }

    /// The whole data space `0..=RAMEND`: registers, IO, SRAM.
    pub fn data(&self) -> &[u8] {
        // SAFETY: `data` holds `ramend + 1` bytes for the life of the core; `&self` keeps
        // simavr from running (and writing it) while the slice lives.
        unsafe { std::slice::from_raw_parts((*self.raw()).data, self.ramend() + 1) }
    }

    /// Reads `len` bytes of data space at `addr`.
    pub fn read_data(&self, addr: usize, len: usize) -> Result<Vec<u8>, Error> {
        let d = self.data();
        d.get(addr..addr.saturating_add(len))
            .map(<[u8]>::to_vec)
            .ok_or(Error::OutOfRange {
                what: "data",
                addr,
                len,
                size: d.len(),
            })
    }

    /// Writes bytes of SRAM at `addr` directly (no IO side effects: use it for SRAM, not for
    /// peripheral registers).
    pub fn write_data(&mut self, addr: usize, bytes: &[u8]) -> Result<(), Error> {
        let size = self.ramend() + 1;
        if addr.checked_add(bytes.len()).is_none_or(|e| e > size) {
            return Err(Error::OutOfRange {
                what: "data",
                addr,
                len: bytes.len(),
                size,
            });
        }
        // SAFETY: in range (checked), exclusive access through `&mut self`.
        unsafe {
            ptr::copy_nonoverlapping(bytes.as_ptr(), (*self.raw()).data.add(addr), bytes.len())
        };
        Ok(())
    }

    /// The value of an ELF symbol as the linker gave it (data addresses carry the 0x800000
    /// offset; see [`Avr::data_symbol`]).
    pub fn symbol(&self, name: &str) -> Option<u32> {
        self.symbols.get(name).copied()
    }

    /// A data-space symbol as an SRAM address (0x800000 offset removed).
    pub fn data_symbol(&self, name: &str) -> Option<usize> {
        self.symbol(name)
            .filter(|&v| (0x80_0000..0x81_0000).contains(&v))
            .map(|v| (v - 0x80_0000) as usize)
    }

    /// Where static data (.data + .bss) ends: `__heap_start`, else `_end`, else `__bss_end`.
    pub fn static_data_end(&self) -> Option<usize> {
        ["__heap_start", "_end", "__bss_end"]
            .iter()
            .find_map(|n| self.data_symbol(n))
    }

    fn paint_stack(&mut self) {
        let Some(start) = self.static_data_end() else {
            return;
        };
        let end = self.ramend();
        if start > end {
            return;
        }
        let fill = vec![STACK_PAINT; end - start + 1];
        if self.write_data(start, &fill).is_ok() {
            self.paint = Some((start, end));
        }
    }

    /// Deepest stack use so far in bytes below RAMEND, measured by painting: free SRAM
    /// (`static_data_end()..=RAMEND`) was filled with [`STACK_PAINT`] at load, and this scans from
    /// the bottom for the first overwritten byte. `None` if the ELF has none of the symbols of
    /// [`Avr::static_data_end`]. A pushed byte equal to the paint at the very bottom goes
    /// unnoticed (under-reads by that byte); heap use (none in this project) would count as
    /// stack.
    pub fn stack_peak(&self) -> Option<usize> {
        let (start, end) = self.paint?;
        let region = &self.data()[start..=end];
        let first = region
            .iter()
            .position(|&b| b != STACK_PAINT)
            .unwrap_or(region.len());
        Some(region.len() - first)
    }

    /// Bytes of flash the program occupies (`.text` + the `.data` initialisers that follow it):
    /// the `__data_load_end` symbol avr-gcc's linker script defines, else `_etext`.
    pub fn flash_size(&self) -> Option<usize> {
        ["__data_load_end", "_etext"]
            .iter()
            .find_map(|n| self.symbol(n))
            .map(|v| v as usize)
    }

    /// Bytes of static data (`static_data_end() - 0x100`, the start of SRAM).
    pub fn static_data_size(&self) -> Option<usize> {
        self.static_data_end().map(|e| e.saturating_sub(0x100))
    }

    /// The program counter (byte address in flash).
    pub fn pc(&self) -> u32 {
        // SAFETY: reading a field of the live core.
        unsafe { (*self.raw()).pc }
    }

    /// Like [`Avr::run_until`], one instruction at a time, charging each instruction's cycles to
    /// the function it belongs to (the nearest text symbol at or below the PC): where the time of
    /// a stretch of firmware goes. About ten times slower than `run_until`; a dev tool.
    pub fn profile_until(&mut self, target: u64) -> Profile {
        self.profile_until_output(target, false)
    }

    /// [`Avr::profile_until`], stopping early (when `at_output`) right after the instruction
    /// that writes a UART byte: a firmware's phases split at its marker bytes.
    pub fn profile_until_output(&mut self, target: u64, at_output: bool) -> Profile {
        let mut by_pc: HashMap<u32, u64> = HashMap::new();
        let out = self.uart_output().len();
        while self.cycle() < target && self.state().is_alive() {
            let (pc, c) = (self.pc(), self.cycle());
            self.run_until(c + 1);
            *by_pc.entry(pc).or_default() += self.cycle() - c;
            if at_output && self.uart_output().len() != out {
                break;
            }
        }
        let mut text: Vec<(u32, &str)> = self
            .symbols
            .iter()
            .filter(|(_, &a)| a < 0x80_0000)
            .map(|(n, &a)| (a, n.as_str()))
            .collect();
        text.sort();
        let mut by_fn: HashMap<String, u64> = HashMap::new();
        for (pc, c) in by_pc {
            let i = text.partition_point(|&(a, _)| a <= pc);
            let name = if i == 0 { "?" } else { text[i - 1].1 };
            *by_fn.entry(name.to_string()).or_default() += c;
        }
        let mut functions: Vec<(String, u64)> = by_fn.into_iter().collect();
        functions.sort_by(|a, b| b.1.cmp(&a.1).then_with(|| a.0.cmp(&b.0)));
        Profile { functions }
    }

    /// Sets simavr's log level for this core (0 none, 1 output, 2 errors — the default —, 3
    /// warnings, 4 trace, 5 debug).
    pub fn set_log_level(&mut self, level: u8) {
        // SAFETY: writing a bitfield of the live core.
        unsafe { (*self.raw()).set_log(level) }
    }
}

impl Drop for Avr {
    fn drop(&mut self) {
        // SAFETY: the core and `Shared` were created in `load` and are freed exactly once here;
        // `avr_terminate` frees the IO modules and memories but not the `avr_t` itself.
        unsafe {
            ffi::avr_terminate(self.raw());
            free(self.raw().cast());
            drop(Box::from_raw(self.shared.as_ptr()));
        }
    }
}

/// Cycles per function from [`Avr::profile_until`], most expensive first.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Profile {
    /// `(symbol, cycles)`.
    pub functions: Vec<(String, u64)>,
}

impl Profile {
    /// Cycles in all functions.
    pub fn total(&self) -> u64 {
        self.functions.iter().map(|f| f.1).sum()
    }
}

/// Copies simavr's symbol table out of `fw` and frees the C allocations `avr_load_firmware`
/// leaves to the caller (symbols and file name).
unsafe fn take_symbols(fw: &mut ffi::elf_firmware_t) -> HashMap<String, u32> {
    let mut out = HashMap::new();
    if !fw.symbol.is_null() {
        for i in 0..fw.symbolcount as usize {
            let s = *fw.symbol.add(i);
            if s.is_null() {
                continue;
            }
            let name = CStr::from_ptr((*s).symbol.as_ptr())
                .to_string_lossy()
                .into_owned();
            out.entry(name).or_insert((*s).addr);
            free(s.cast());
        }
        free(fw.symbol.cast());
        fw.symbol = ptr::null_mut();
        fw.symbolcount = 0;
    }
    if !fw.file_name.is_null() {
        free(fw.file_name.cast());
        fw.file_name = ptr::null_mut();
    }
    out
}

/// Finds UART0 in the core's IO module list (`avr_uart_t` starts with its `avr_io_t`).
unsafe fn find_uart0(a: *mut ffi::avr_t) -> *mut ffi::avr_uart_t {
    let mut io = (*a).io_port;
    while !io.is_null() {
        if !(*io).kind.is_null() && CStr::from_ptr((*io).kind).to_bytes() == b"uart" {
            let u = io.cast::<ffi::avr_uart_t>();
            if (*u).name as u8 == b'0' {
                return u;
            }
        }
        io = (*io).next;
    }
    ptr::null_mut()
}
