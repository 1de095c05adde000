//! Board layer for the Arduino Uno (ATmega328P) over avr-device.
#![no_std]
