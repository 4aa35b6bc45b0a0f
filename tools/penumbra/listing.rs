//! `penumbra devices` and `penumbra techniques`: what the machine offers and what penumbra
//! runs, as text or JSON.

use penumbra::techniques::{registry, KnobDefault};

/// `penumbra devices`: every Vulkan device, what it offers and whether penumbra can use it.
pub(crate) fn devices(json: bool) -> anyhow::Result<()> {
    let list = penumbra::gpu::enumerate_devices()?;
    if json {
        println!("{}", serde_json::to_string_pretty(&list)?);
        return Ok(());
    }
    for (i, d) in list.iter().enumerate() {
        println!(
            "{i}: {} ({}, Vulkan {})",
            d.name, d.device_type, d.api_version
        );
        println!("   driver: {}", d.driver);
        match &d.usable {
            Ok(()) => println!("   usable by penumbra: yes"),
            Err(why) => println!("   usable by penumbra: no ({why})"),
        }
        let yn = |b: bool| if b { "yes" } else { "no" };
        println!(
            "   timestamps: {} valid bits, {} ns/tick; subgroup size {}, arithmetic {}, shuffle {}",
            d.timestamp_valid_bits,
            d.timestamp_period,
            d.subgroup_size,
            yn(d.subgroup_arithmetic),
            yn(d.subgroup_shuffle)
        );
        println!(
            "   float64 {}, int64 {}, int64 atomics {}, depth bias clamp {}, linear depth filtering {}",
            yn(d.float64),
            yn(d.int64),
            yn(d.int64_atomics),
            yn(d.depth_bias_clamp),
            yn(d.depth_linear_filter)
        );
        println!(
            "   conservative raster {}, fragment interlock {}, ray query {}",
            yn(d.conservative_rasterization),
            yn(d.fragment_shader_interlock),
            yn(d.ray_query)
        );
        println!(
            "   shared memory {} KiB, storage buffer range {} MiB, max 2D image {}",
            d.max_shared_memory / 1024,
            d.max_storage_buffer_range / (1024 * 1024),
            d.max_image_dimension_2d
        );
    }
    Ok(())
}

/// `penumbra techniques`: every technique with its knobs, defaults and ranges.
pub(crate) fn techniques(json: bool) -> anyhow::Result<()> {
    if json {
        let list: Vec<_> = registry()
            .iter()
            .map(|t| {
                serde_json::json!({"name": t.name, "summary": t.summary, "knobs": t.all_knobs()})
            })
            .collect();
        println!("{}", serde_json::to_string_pretty(&list)?);
        return Ok(());
    }
    for t in registry() {
        println!("{}: {}", t.name, t.summary);
        for k in t.all_knobs() {
            let default = match k.default {
                KnobDefault::Value(v) => match k.names.get(v as usize) {
                    Some(name) => name.to_string(),
                    None => format!("{v}"),
                },
                KnobDefault::Scene(key) => format!("scene's {key}"),
            };
            println!(
                "    {:<20} default {:<24} range [{}, {}]{}  {}",
                k.name,
                default,
                k.min,
                k.max,
                if !k.names.is_empty() {
                    format!(" {}", k.names.join("|"))
                } else if k.integer {
                    " integer".to_string()
                } else {
                    String::new()
                },
                k.summary
            );
        }
    }
    Ok(())
}
