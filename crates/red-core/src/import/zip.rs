//! Just enough of the zip format to read numpy's `.npz` files: the central
//! directory (with zip64 sizes, which numpy always asks for), stored and
//! deflated entries, CRC checks. Every offset and size is checked against
//! the input before use.

use std::io::Read;

/// One file of the archive, decompressed.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Entry {
    pub name: String,
    pub data: Vec<u8>,
}

/// No `.npz` entry of demonstrations comes near this; larger claims are
/// taken for corruption (or a zip bomb).
const MAX_ENTRY: u64 = 1 << 31;

fn u16_at(b: &[u8], at: usize) -> Result<u16, String> {
    b.get(at..at + 2)
        .map(|s| u16::from_le_bytes([s[0], s[1]]))
        .ok_or_else(|| format!("truncated zip: no 2 bytes at {at}"))
}

fn u32_at(b: &[u8], at: usize) -> Result<u32, String> {
    b.get(at..at + 4)
        .map(|s| u32::from_le_bytes([s[0], s[1], s[2], s[3]]))
        .ok_or_else(|| format!("truncated zip: no 4 bytes at {at}"))
}

fn u64_at(b: &[u8], at: usize) -> Result<u64, String> {
    b.get(at..at + 8)
        .map(|s| {
            let mut a = [0u8; 8];
            a.copy_from_slice(s);
            u64::from_le_bytes(a)
        })
        .ok_or_else(|| format!("truncated zip: no 8 bytes at {at}"))
}

fn to_usize(v: u64, what: &str) -> Result<usize, String> {
    usize::try_from(v).map_err(|_| format!("zip {what} {v} is too large"))
}

/// Reads every entry of the zip archive in `bytes`.
pub(crate) fn read_entries(bytes: &[u8]) -> Result<Vec<Entry>, String> {
    let eocd = find_eocd(bytes)?;
    let mut count = u64::from(u16_at(bytes, eocd + 10)?);
    let mut cd_size = u64::from(u32_at(bytes, eocd + 12)?);
    let mut cd_offset = u64::from(u32_at(bytes, eocd + 16)?);
    if count == 0xFFFF || cd_size == 0xFFFF_FFFF || cd_offset == 0xFFFF_FFFF {
        // The zip64 end record, found through its locator just before.
        let loc = eocd
            .checked_sub(20)
            .filter(|&l| u32_at(bytes, l).ok() == Some(0x0706_4b50))
            .ok_or("zip64 sizes without a zip64 locator")?;
        let rec = to_usize(u64_at(bytes, loc + 8)?, "offset")?;
        if u32_at(bytes, rec)? != 0x0606_4b50 {
            return Err("zip64 end record missing".into());
        }
        count = u64_at(bytes, rec + 32)?;
        cd_size = u64_at(bytes, rec + 40)?;
        cd_offset = u64_at(bytes, rec + 48)?;
    }
    let cd_start = to_usize(cd_offset, "offset")?;
    let cd_end = cd_start
        .checked_add(to_usize(cd_size, "size")?)
        .filter(|&e| e <= bytes.len())
        .ok_or("zip central directory lies outside the file (truncated?)")?;
    // Each central record is at least 46 bytes, which bounds the count.
    if count > (cd_end - cd_start) as u64 / 46 {
        return Err(format!(
            "zip claims {count} entries, more than its central directory can hold"
        ));
    }
    let mut out = Vec::with_capacity(count as usize);
    let mut at = cd_start;
    for i in 0..count {
        if u32_at(bytes, at)? != 0x0201_4b50 {
            return Err(format!("zip central record {i} is corrupt"));
        }
        let flags = u16_at(bytes, at + 8)?;
        let method = u16_at(bytes, at + 10)?;
        let crc = u32_at(bytes, at + 16)?;
        let mut csize = u64::from(u32_at(bytes, at + 20)?);
        let mut usize_ = u64::from(u32_at(bytes, at + 24)?);
        let nlen = usize::from(u16_at(bytes, at + 28)?);
        let xlen = usize::from(u16_at(bytes, at + 30)?);
        let clen = usize::from(u16_at(bytes, at + 32)?);
        let mut local = u64::from(u32_at(bytes, at + 42)?);
        let name_at = at + 46;
        let name = bytes
            .get(name_at..name_at + nlen)
            .ok_or("truncated zip central directory")?;
        let name = String::from_utf8_lossy(name).into_owned();
        let extra = bytes
            .get(name_at + nlen..name_at + nlen + xlen)
            .ok_or("truncated zip central directory")?;
        read_zip64_extra(extra, &mut usize_, &mut csize, &mut local)?;
        at = name_at + nlen + xlen + clen;
        if flags & 1 != 0 {
            return Err(format!("zip entry {name} is encrypted"));
        }
        if usize_ > MAX_ENTRY {
            return Err(format!("zip entry {name} claims {usize_} bytes, too many"));
        }
        let data = entry_data(
            bytes,
            &name,
            to_usize(local, "offset")?,
            csize,
            usize_,
            method,
        )?;
        let mut c = flate2::Crc::new();
        c.update(&data);
        if c.sum() != crc {
            return Err(format!("zip entry {name} fails its CRC check (corrupt)"));
        }
        out.push(Entry { name, data });
    }
    Ok(out)
}

fn find_eocd(bytes: &[u8]) -> Result<usize, String> {
    if bytes.len() < 22 {
        return Err("not a zip archive (too short)".into());
    }
    let lowest = bytes.len().saturating_sub(22 + 0xFFFF);
    (lowest..=bytes.len() - 22)
        .rev()
        .find(|&i| bytes[i..i + 4] == [0x50, 0x4b, 0x05, 0x06])
        .ok_or_else(|| "not a zip archive, or truncated (no end of central directory)".into())
}

fn read_zip64_extra(
    mut extra: &[u8],
    usize_: &mut u64,
    csize: &mut u64,
    local: &mut u64,
) -> Result<(), String> {
    while extra.len() >= 4 {
        let id = u16_at(extra, 0)?;
        let len = usize::from(u16_at(extra, 2)?);
        let body = extra.get(4..4 + len).ok_or("truncated zip extra field")?;
        if id == 1 {
            let mut k = 0;
            for v in [&mut *usize_, &mut *csize, &mut *local] {
                if *v == 0xFFFF_FFFF {
                    *v = u64_at(body, k)?;
                    k += 8;
                }
            }
        }
        extra = &extra[4 + len..];
    }
    Ok(())
}

fn entry_data(
    bytes: &[u8],
    name: &str,
    local: usize,
    csize: u64,
    usize_: u64,
    method: u16,
) -> Result<Vec<u8>, String> {
    if u32_at(bytes, local)? != 0x0403_4b50 {
        return Err(format!("zip entry {name}: local header is corrupt"));
    }
    let nlen = usize::from(u16_at(bytes, local + 26)?);
    let xlen = usize::from(u16_at(bytes, local + 28)?);
    let start = local + 30 + nlen + xlen;
    let end = start
        .checked_add(to_usize(csize, "size")?)
        .filter(|&e| e <= bytes.len())
        .ok_or_else(|| format!("zip entry {name} runs past the end of the file (truncated?)"))?;
    let raw = &bytes[start..end];
    let data = match method {
        0 => raw.to_vec(),
        8 => {
            let mut out = Vec::new();
            flate2::read::DeflateDecoder::new(raw)
                .take(usize_ + 1)
                .read_to_end(&mut out)
                .map_err(|e| format!("zip entry {name}: corrupt deflate data: {e}"))?;
            out
        }
        m => {
            return Err(format!(
                "zip entry {name} uses compression method {m}; only stored (0) and deflate (8) \
                 are supported"
            ));
        }
    };
    if data.len() as u64 != usize_ {
        return Err(format!(
            "zip entry {name} holds {} bytes, its directory says {usize_}",
            data.len()
        ));
    }
    Ok(data)
}
