//! `est-sink` is linked even when it overflows the ATmega328P's flash (`--noinhibit-exec`: the
//! overflow is then a linker message, not an error), so that its size can be measured while it
//! does not fit; simavr refuses such an ELF, and the harness says why.
fn main() {
    println!("cargo:rustc-link-arg-bin=est-sink=-Wl,--noinhibit-exec");
}
