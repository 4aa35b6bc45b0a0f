//! A minimal SPIR-V reflector: entry stage, workgroup size, descriptor bindings, and the
//! push-constant block's size and members (name, offset, size).
//!
//! The shader is the one source of truth for its interface: pipelines build their descriptor-set
//! layouts from what the module declares, dispatches round thread counts up by the declared
//! `local_size`, and pushes are checked against the declared push-constant block size. The
//! block's member offsets come from its `OpMemberDecorate … Offset` and the names from
//! `OpMemberName`, which `compile-shaders` keeps for push blocks (the optimizer strips every
//! other name), so the layout tests can compare each `#[repr(C)]` twin field by field with
//! [`compare_push_layout`]. Only what
//! penumbra's GLSL uses is understood (set 0 bindings of buffers, storage/sampled images and
//! combined samplers, literal local sizes); anything else is an error, not a guess.

use std::collections::HashMap;

use ash::vk;

use crate::error::{Error, Result};

/// One descriptor binding as declared by a shader.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BindingInfo {
    /// Descriptor set (penumbra uses 0 only).
    pub set: u32,
    /// Binding number.
    pub binding: u32,
    /// Descriptor type.
    pub kind: vk::DescriptorType,
    /// Whether the shader only reads it (`readonly`), which lets read-after-read skip barriers.
    pub read_only: bool,
}

/// What a shader module declares.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ShaderInterface {
    /// The entry point's stage.
    pub stage: vk::ShaderStageFlags,
    /// `local_size` of a compute shader (1,1,1 otherwise).
    pub local_size: [u32; 3],
    /// Descriptor bindings sorted by (set, binding).
    pub bindings: Vec<BindingInfo>,
    /// Size in bytes of the push-constant block (0 if none).
    pub push_constant_size: u32,
    /// The push-constant block's members in declaration order (empty if none).
    pub push_constant_members: Vec<PushMember>,
}

/// One member of a push-constant block, as the SPIR-V lays it out.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PushMember {
    /// The GLSL member name (`OpMemberName`); empty when the module carries no name for it.
    pub name: String,
    /// Byte offset in the block (`Offset` decoration).
    pub offset: u32,
    /// Size in bytes.
    pub size: u32,
}

/// One field of a Rust push-constant struct: name, `offset_of!` and size.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RustField {
    /// Field name.
    pub name: &'static str,
    /// `std::mem::offset_of!`.
    pub offset: usize,
    /// `size_of` the field's type.
    pub size: usize,
}

/// Whether a member (GLSL or Rust) only pads the block to its size: `pad`, `pad0`, `pad1`, ….
fn is_padding(name: &str) -> bool {
    name.strip_prefix("pad")
        .is_some_and(|rest| rest.chars().all(|c| c.is_ascii_digit()))
}

/// Compares a Rust push-constant struct (`fields` in declaration order, `size_of` = `size`)
/// with the block a shader declares, by member name: every GLSL member must have a Rust field
/// of the same name at the same offset with the same size and vice versa, and the sizes must
/// agree. Padding members (`pad`, `pad0`, …) need no twin, since Rust and GLSL pad differently
/// (`[i32; 2]` against two `int`s), but a Rust padding field must not cover a real member
/// (that member would then have no twin). Because `bytemuck::Pod` forbids implicit padding,
/// fields whose sizes add up to `size` are all the struct's fields. Returns every mismatch, one
/// line each; empty when the layouts agree.
pub fn compare_push_layout(
    interface: &ShaderInterface,
    fields: &[RustField],
    size: usize,
) -> Vec<String> {
    let mut problems = Vec::new();
    if interface.push_constant_size as usize != size {
        problems.push(format!(
            "block is {} bytes, the Rust struct {size}",
            interface.push_constant_size
        ));
    }
    let listed: usize = fields.iter().map(|f| f.size).sum();
    if listed != size {
        problems.push(format!(
            "the listed Rust fields cover {listed} of the struct's {size} bytes: list every field"
        ));
    }
    for m in &interface.push_constant_members {
        if m.name.is_empty() {
            problems.push(format!(
                "member at offset {} has no name in the SPIR-V (run compile-shaders)",
                m.offset
            ));
            continue;
        }
        if is_padding(&m.name) {
            continue;
        }
        match fields.iter().find(|f| f.name == m.name) {
            None => problems.push(format!("GLSL member '{}' has no Rust field", m.name)),
            Some(f) if (f.offset, f.size) != (m.offset as usize, m.size as usize) => {
                problems.push(format!(
                    "'{}': GLSL offset {} size {}, Rust offset {} size {}",
                    m.name, m.offset, m.size, f.offset, f.size
                ))
            }
            Some(_) => {}
        }
    }
    for f in fields.iter().filter(|f| !is_padding(f.name)) {
        if !interface
            .push_constant_members
            .iter()
            .any(|m| m.name == f.name)
        {
            problems.push(format!("Rust field '{}' has no GLSL member", f.name));
        }
    }
    problems
}

const OP_MEMBER_NAME: u32 = 6;
const OP_ENTRY_POINT: u32 = 15;
const OP_EXECUTION_MODE: u32 = 16;
const OP_TYPE_INT: u32 = 21;
const OP_TYPE_FLOAT: u32 = 22;
const OP_TYPE_VECTOR: u32 = 23;
const OP_TYPE_MATRIX: u32 = 24;
const OP_TYPE_IMAGE: u32 = 25;
/// `Dim` operand of `OpTypeImage` for texel buffers.
const DIM_BUFFER: u32 = 5;
const OP_TYPE_SAMPLER: u32 = 26;
const OP_TYPE_SAMPLED_IMAGE: u32 = 27;
const OP_TYPE_ARRAY: u32 = 28;
const OP_TYPE_RUNTIME_ARRAY: u32 = 29;
const OP_TYPE_STRUCT: u32 = 30;
const OP_TYPE_POINTER: u32 = 32;
const OP_CONSTANT: u32 = 43;
const OP_VARIABLE: u32 = 59;
const OP_DECORATE: u32 = 71;
const OP_MEMBER_DECORATE: u32 = 72;

const DEC_BLOCK: u32 = 2;
const DEC_BUFFER_BLOCK: u32 = 3;
const DEC_MATRIX_STRIDE: u32 = 7;
const DEC_ARRAY_STRIDE: u32 = 6;
const DEC_NON_WRITABLE: u32 = 24;
const DEC_BINDING: u32 = 33;
const DEC_DESCRIPTOR_SET: u32 = 34;
const DEC_OFFSET: u32 = 35;

const SC_UNIFORM_CONSTANT: u32 = 0;
const SC_UNIFORM: u32 = 2;
const SC_PUSH_CONSTANT: u32 = 9;
const SC_STORAGE_BUFFER: u32 = 12;

#[derive(Default)]
struct Module {
    types: HashMap<u32, Vec<u32>>,
    constants: HashMap<u32, u32>,
    decorations: HashMap<u32, Vec<(u32, u32)>>,
    member_decorations: HashMap<(u32, u32), Vec<(u32, u32)>>,
    member_names: HashMap<(u32, u32), String>,
    variables: Vec<(u32, u32, u32)>,
}

impl Module {
    fn decoration(&self, id: u32, dec: u32) -> Option<u32> {
        self.decorations
            .get(&id)
            .and_then(|d| d.iter().find(|(k, _)| *k == dec).map(|(_, v)| *v))
    }

    fn member_decoration(&self, id: u32, member: u32, dec: u32) -> Option<u32> {
        self.member_decorations
            .get(&(id, member))
            .and_then(|d| d.iter().find(|(k, _)| *k == dec).map(|(_, v)| *v))
    }

    /// Size in bytes of member `m` (type `member`) of struct `id`; a matrix member's size comes
    /// from its `MatrixStride`.
    fn member_size(&self, id: u32, m: u32, member: u32) -> Option<u32> {
        match self.member_decoration(id, m, DEC_MATRIX_STRIDE) {
            Some(stride) => Some(stride * self.types.get(&member)?.get(3).copied()?),
            None => self.size_of(member),
        }
    }

    /// The members of a block struct with their names, offsets and sizes.
    fn members(&self, id: u32) -> Option<Vec<PushMember>> {
        let t = self.types.get(&id).filter(|t| t[0] == OP_TYPE_STRUCT)?;
        t[2..]
            .iter()
            .enumerate()
            .map(|(m, &member)| {
                let m = m as u32;
                Some(PushMember {
                    name: self.member_names.get(&(id, m)).cloned().unwrap_or_default(),
                    offset: self.member_decoration(id, m, DEC_OFFSET)?,
                    size: self.member_size(id, m, member)?,
                })
            })
            .collect()
    }

    /// Size in bytes of a type laid out with explicit offsets/strides (std140/std430 blocks).
    fn size_of(&self, id: u32) -> Option<u32> {
        let t = self.types.get(&id)?;
        match t[0] {
            OP_TYPE_INT | OP_TYPE_FLOAT => Some(t[2] / 8),
            OP_TYPE_VECTOR => Some(self.size_of(t[2])? * t[3]),
            OP_TYPE_MATRIX => {
                let stride = self.size_of(t[2])?;
                Some(stride * t[3])
            }
            OP_TYPE_ARRAY => {
                let stride = self.decoration(id, DEC_ARRAY_STRIDE)?;
                Some(stride * self.constants.get(&t[3])?)
            }
            OP_TYPE_STRUCT => {
                let mut end = 0;
                for (m, &member) in t[2..].iter().enumerate() {
                    let offset = self.member_decoration(id, m as u32, DEC_OFFSET)?;
                    let size = self.member_size(id, m as u32, member)?;
                    end = end.max(offset + size);
                }
                Some(end)
            }
            _ => None,
        }
    }
}

/// Reads a shader's interface from its SPIR-V words.
pub fn reflect(name: &str, words: &[u32]) -> Result<ShaderInterface> {
    let err = |message: String| Error::Shader {
        name: name.to_string(),
        message,
    };
    if words.len() < 5 || words[0] != 0x0723_0203 {
        return Err(err("not a SPIR-V module (bad magic number)".into()));
    }
    let mut module = Module::default();
    let mut stage = None;
    let mut local_size = [1, 1, 1];
    let mut i = 5;
    while i < words.len() {
        let count = (words[i] >> 16) as usize;
        let op = words[i] & 0xffff;
        if count == 0 || i + count > words.len() {
            return Err(err(format!("truncated instruction at word {i}")));
        }
        let ins = &words[i..i + count];
        match op {
            OP_ENTRY_POINT => {
                stage = Some(match ins[1] {
                    0 => vk::ShaderStageFlags::VERTEX,
                    4 => vk::ShaderStageFlags::FRAGMENT,
                    5 => vk::ShaderStageFlags::COMPUTE,
                    other => return Err(err(format!("unsupported execution model {other}"))),
                })
            }
            OP_EXECUTION_MODE if ins.len() >= 6 && ins[2] == 17 => {
                local_size = [ins[3], ins[4], ins[5]];
            }
            OP_TYPE_INT
            | OP_TYPE_FLOAT
            | OP_TYPE_VECTOR
            | OP_TYPE_MATRIX
            | OP_TYPE_IMAGE
            | OP_TYPE_SAMPLER
            | OP_TYPE_SAMPLED_IMAGE
            | OP_TYPE_ARRAY
            | OP_TYPE_RUNTIME_ARRAY
            | OP_TYPE_STRUCT => {
                let mut t = vec![op];
                t.extend_from_slice(&ins[1..]);
                module.types.insert(ins[1], t);
            }
            OP_TYPE_POINTER => {
                module
                    .types
                    .insert(ins[1], vec![op, ins[1], ins[2], ins[3]]);
            }
            OP_CONSTANT if ins.len() >= 4 => {
                module.constants.insert(ins[2], ins[3]);
            }
            OP_VARIABLE => module.variables.push((ins[1], ins[2], ins[3])),
            OP_DECORATE if ins.len() >= 3 => module
                .decorations
                .entry(ins[1])
                .or_default()
                .push((ins[2], ins.get(3).copied().unwrap_or(0))),
            OP_MEMBER_NAME if ins.len() >= 3 => {
                module
                    .member_names
                    .insert((ins[1], ins[2]), literal_string(&ins[3..]));
            }
            OP_MEMBER_DECORATE if ins.len() >= 4 => module
                .member_decorations
                .entry((ins[1], ins[2]))
                .or_default()
                .push((ins[3], ins.get(4).copied().unwrap_or(0))),
            _ => {}
        }
        i += count;
    }
    let stage = stage.ok_or_else(|| err("no entry point".into()))?;
    let mut bindings = Vec::new();
    let mut push_constant_size = 0;
    let mut push_constant_members = Vec::new();
    for &(ptr_type, id, storage) in &module.variables {
        let pointee = match module.types.get(&ptr_type) {
            Some(t) if t[0] == OP_TYPE_POINTER => t[3],
            _ => continue,
        };
        if storage == SC_PUSH_CONSTANT {
            push_constant_size = module
                .size_of(pointee)
                .ok_or_else(|| err("cannot size the push-constant block".into()))?;
            push_constant_members = module
                .members(pointee)
                .ok_or_else(|| err("cannot lay out the push-constant block's members".into()))?;
            continue;
        }
        if !matches!(
            storage,
            SC_UNIFORM_CONSTANT | SC_UNIFORM | SC_STORAGE_BUFFER
        ) {
            continue;
        }
        let (Some(set), Some(binding)) = (
            module.decoration(id, DEC_DESCRIPTOR_SET),
            module.decoration(id, DEC_BINDING),
        ) else {
            continue;
        };
        let mut inner = pointee;
        if let Some(t) = module.types.get(&inner) {
            if t[0] == OP_TYPE_ARRAY || t[0] == OP_TYPE_RUNTIME_ARRAY {
                return Err(err(format!(
                    "binding {binding}: descriptor arrays are not supported"
                )));
            }
        }
        let t = module
            .types
            .get(&inner)
            .ok_or_else(|| err(format!("binding {binding}: unknown type")))?;
        let all_members_read_only = |struct_id: u32, members: usize| {
            (0..members as u32).all(|m| {
                module
                    .member_decoration(struct_id, m, DEC_NON_WRITABLE)
                    .is_some()
            })
        };
        let var_read_only = module.decoration(id, DEC_NON_WRITABLE).is_some();
        let (kind, read_only) = match (storage, t[0]) {
            (SC_STORAGE_BUFFER, OP_TYPE_STRUCT) => (
                vk::DescriptorType::STORAGE_BUFFER,
                var_read_only || all_members_read_only(inner, t.len() - 2),
            ),
            (SC_UNIFORM, OP_TYPE_STRUCT) => {
                if module.decoration(inner, DEC_BUFFER_BLOCK).is_some() {
                    (
                        vk::DescriptorType::STORAGE_BUFFER,
                        var_read_only || all_members_read_only(inner, t.len() - 2),
                    )
                } else if module.decoration(inner, DEC_BLOCK).is_some() {
                    (vk::DescriptorType::UNIFORM_BUFFER, true)
                } else {
                    return Err(err(format!("binding {binding}: uniform without Block")));
                }
            }
            (SC_UNIFORM_CONSTANT, OP_TYPE_IMAGE) => match (t.get(3), t.get(7)) {
                (Some(&DIM_BUFFER), Some(2)) => {
                    (vk::DescriptorType::STORAGE_TEXEL_BUFFER, var_read_only)
                }
                (Some(&DIM_BUFFER), Some(1)) => (vk::DescriptorType::UNIFORM_TEXEL_BUFFER, true),
                (_, Some(2)) => (vk::DescriptorType::STORAGE_IMAGE, var_read_only),
                (_, Some(1)) => (vk::DescriptorType::SAMPLED_IMAGE, true),
                _ => return Err(err(format!("binding {binding}: unknown image kind"))),
            },
            (SC_UNIFORM_CONSTANT, OP_TYPE_SAMPLED_IMAGE) => {
                // A samplerBuffer: the sampled image of a buffer-dimensioned image.
                let image = t.get(2).and_then(|i| module.types.get(i));
                if image.and_then(|i| i.get(3)) == Some(&DIM_BUFFER) {
                    (vk::DescriptorType::UNIFORM_TEXEL_BUFFER, true)
                } else {
                    (vk::DescriptorType::COMBINED_IMAGE_SAMPLER, true)
                }
            }
            (SC_UNIFORM_CONSTANT, OP_TYPE_SAMPLER) => (vk::DescriptorType::SAMPLER, true),
            _ => {
                inner = t[0];
                return Err(err(format!(
                    "binding {binding}: unsupported descriptor (opcode {inner})"
                )));
            }
        };
        bindings.push(BindingInfo {
            set,
            binding,
            kind,
            read_only,
        });
    }
    bindings.sort_by_key(|b| (b.set, b.binding));
    if let Some(b) = bindings.iter().find(|b| b.set != 0) {
        return Err(err(format!(
            "binding {} uses set {}; penumbra shaders use set 0 only",
            b.binding, b.set
        )));
    }
    Ok(ShaderInterface {
        stage,
        local_size,
        bindings,
        push_constant_size,
        push_constant_members,
    })
}

/// A SPIR-V literal string: UTF-8 bytes packed little-endian into words, NUL-terminated.
fn literal_string(words: &[u32]) -> String {
    let bytes: Vec<u8> = words
        .iter()
        .flat_map(|w| w.to_le_bytes())
        .take_while(|&b| b != 0)
        .collect();
    String::from_utf8_lossy(&bytes).into_owned()
}

/// Turns SPIR-V bytes into words, checking alignment and the magic number.
pub fn words_from_bytes(name: &str, bytes: &[u8]) -> Result<Vec<u32>> {
    if bytes.len() % 4 != 0 || bytes.len() < 20 {
        return Err(Error::Shader {
            name: name.to_string(),
            message: format!(
                "SPIR-V size {} is not a positive multiple of 4",
                bytes.len()
            ),
        });
    }
    Ok(bytes
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect())
}
