//! Checks a firmware file before simavr's loader reads it: simavr's loader ends the whole process
//! (`exit(1)`) on an ELF whose segments run past the end of the file, and writes its complaints
//! about other bad files to stderr. [`inspect`] reads the file with the `object` crate instead and
//! says what is wrong with it in an error ([`ElfProblem`]): not an ELF, not for the AVR, cut
//! short, no program to load. It also hands out what tells a firmware's role: its `.eeprom`
//! image and its symbol names.

use std::fmt;
use std::path::Path;

use object::elf;
use object::read::elf::{ElfFile32, FileHeader, ProgramHeader};
use object::{Endianness, Object, ObjectSection, ObjectSymbol, SectionKind};

/// What is wrong with a firmware file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ElfProblem {
    /// The file is empty.
    Empty,
    /// The file does not start as an ELF does.
    NotElf,
    /// An ELF, but not a 32-bit little-endian one (AVR ELFs are).
    NotElf32,
    /// An ELF for another machine (`e_machine`; AVR is 83).
    NotAvr {
        /// The ELF's machine number.
        machine: u16,
    },
    /// Its headers, a segment or a section reach past the end of the file: a truncated copy.
    Truncated {
        /// What reaches past the end.
        what: String,
        /// The file's size, bytes.
        size: u64,
    },
    /// No loadable segment: nothing for the flash.
    NoProgram,
}

impl fmt::Display for ElfProblem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ElfProblem::Empty => f.write_str("the file is empty"),
            ElfProblem::NotElf => f.write_str("not an ELF file (no ELF header)"),
            ElfProblem::NotElf32 => {
                f.write_str("not an AVR ELF (AVR ELFs are 32-bit little-endian)")
            }
            ElfProblem::NotAvr { machine } => write!(
                f,
                "an ELF for another machine (e_machine {machine}; the AVR's is {})",
                elf::EM_AVR
            ),
            ElfProblem::Truncated { what, size } => write!(
                f,
                "truncated: {what} reaches past the end of the file ({size} bytes); copy or \
                 build it again"
            ),
            ElfProblem::NoProgram => f.write_str("no loadable segment (no program in it)"),
        }
    }
}

/// What [`inspect`] found in a sound AVR ELF.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ElfImage {
    /// The `.eeprom` section's bytes, if it has one.
    pub eeprom: Option<Vec<u8>>,
    /// The names of its symbols.
    pub symbols: Vec<String>,
}

/// Reads and checks the ELF bytes `data` (see the module docs).
pub fn inspect_bytes(data: &[u8]) -> Result<ElfImage, ElfProblem> {
    let size = data.len() as u64;
    if data.is_empty() {
        return Err(ElfProblem::Empty);
    }
    if !data.starts_with(&elf::ELFMAG) {
        return Err(ElfProblem::NotElf);
    }
    // e_ident: the class (32 or 64 bits) at byte 4, the byte order at byte 5.
    if data.get(4) != Some(&elf::ELFCLASS32) || data.get(5) != Some(&elf::ELFDATA2LSB) {
        return Err(if data.len() < 6 {
            ElfProblem::Truncated {
                what: "the ELF header".into(),
                size,
            }
        } else {
            ElfProblem::NotElf32
        });
    }
    let truncated = |what: &str| ElfProblem::Truncated {
        what: what.to_string(),
        size,
    };
    let header =
        elf::FileHeader32::<Endianness>::parse(data).map_err(|_| truncated("the ELF header"))?;
    let endian = header.endian().map_err(|_| ElfProblem::NotElf32)?;
    let machine = header.e_machine(endian);
    if machine != elf::EM_AVR {
        return Err(ElfProblem::NotAvr { machine });
    }
    let segments = header
        .program_headers(endian, data)
        .map_err(|_| truncated("the program header table"))?;
    let mut loadable = 0;
    for (i, ph) in segments.iter().enumerate() {
        if ph.p_type(endian) != elf::PT_LOAD || ph.p_filesz(endian) == 0 {
            continue;
        }
        loadable += 1;
        let end = u64::from(ph.p_offset(endian)) + u64::from(ph.p_filesz(endian));
        if end > size {
            return Err(truncated(&format!("segment {i}")));
        }
    }
    if loadable == 0 {
        return Err(ElfProblem::NoProgram);
    }
    let file =
        ElfFile32::<Endianness>::parse(data).map_err(|_| truncated("the section header table"))?;
    let mut image = ElfImage::default();
    for section in file.sections() {
        let name = section.name().unwrap_or("?");
        if section.kind() == SectionKind::UninitializedData {
            continue;
        }
        let bytes = section
            .data()
            .map_err(|_| truncated(&format!("section `{name}`")))?;
        if name == ".eeprom" {
            image.eeprom = Some(bytes.to_vec());
        }
    }
    for sym in file.symbols() {
        if let Ok(name) = sym.name() {
            if !name.is_empty() {
                image.symbols.push(name.to_string());
            }
        }
    }
    Ok(image)
}

/// Reads and checks the ELF file at `path` (see the module docs).
pub fn inspect(path: &Path) -> Result<ElfImage, crate::Error> {
    let data = std::fs::read(path).map_err(|e| crate::Error::Io(path.to_path_buf(), e))?;
    inspect_bytes(&data).map_err(|p| crate::Error::BadElf(path.to_path_buf(), p))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A minimal AVR ELF: the header, one program header, one loadable byte.
    fn tiny_avr() -> Vec<u8> {
        let mut v = vec![0u8; 52 + 32 + 2];
        v[..4].copy_from_slice(&elf::ELFMAG);
        v[4] = elf::ELFCLASS32;
        v[5] = elf::ELFDATA2LSB;
        v[6] = 1; // EV_CURRENT
        v[16..18].copy_from_slice(&elf::ET_EXEC.to_le_bytes());
        v[18..20].copy_from_slice(&elf::EM_AVR.to_le_bytes());
        v[20..24].copy_from_slice(&1u32.to_le_bytes()); // e_version
        v[28..32].copy_from_slice(&52u32.to_le_bytes()); // e_phoff
        v[40..42].copy_from_slice(&52u16.to_le_bytes()); // e_ehsize
        v[42..44].copy_from_slice(&32u16.to_le_bytes()); // e_phentsize
        v[44..46].copy_from_slice(&1u16.to_le_bytes()); // e_phnum
        v[46..48].copy_from_slice(&40u16.to_le_bytes()); // e_shentsize
        let ph = 52;
        v[ph..ph + 4].copy_from_slice(&elf::PT_LOAD.to_le_bytes());
        v[ph + 4..ph + 8].copy_from_slice(&84u32.to_le_bytes()); // p_offset
        v[ph + 16..ph + 20].copy_from_slice(&2u32.to_le_bytes()); // p_filesz
        v[ph + 20..ph + 24].copy_from_slice(&2u32.to_le_bytes()); // p_memsz
        v
    }

    #[test]
    fn a_sound_avr_elf_passes() {
        assert_eq!(inspect_bytes(&tiny_avr()), Ok(ElfImage::default()));
    }

    #[test]
    fn every_problem_is_named() {
        assert_eq!(inspect_bytes(&[]), Err(ElfProblem::Empty));
        assert_eq!(inspect_bytes(b"#!/bin/sh\n"), Err(ElfProblem::NotElf));
        let mut x86 = tiny_avr();
        x86[18..20].copy_from_slice(&elf::EM_386.to_le_bytes());
        assert_eq!(inspect_bytes(&x86), Err(ElfProblem::NotAvr { machine: 3 }));
        let mut elf64 = tiny_avr();
        elf64[4] = elf::ELFCLASS64;
        assert_eq!(inspect_bytes(&elf64), Err(ElfProblem::NotElf32));
        let whole = tiny_avr();
        for cut in [5, 30, 60, whole.len() - 1] {
            assert!(
                matches!(
                    inspect_bytes(&whole[..cut]),
                    Err(ElfProblem::Truncated { .. })
                ),
                "cut at {cut}: {:?}",
                inspect_bytes(&whole[..cut])
            );
        }
        let mut empty = tiny_avr();
        empty[52..56].copy_from_slice(&elf::PT_NOTE.to_le_bytes());
        assert_eq!(inspect_bytes(&empty), Err(ElfProblem::NoProgram));
        let msg = ElfProblem::Truncated {
            what: "segment 0".into(),
            size: 85,
        }
        .to_string();
        assert!(
            msg.contains("segment 0") && msg.contains("85 bytes"),
            "{msg}"
        );
    }
}
