//! Stuck chips and bad input: named errors, the destination table, the watchdog.

use super::*;
use dualstream::machine::ChipError;
use dualstream::render::RenderError;

#[test]
fn bad_chip_configs_are_named() {
    let mut c = Config::default();
    c.chip.tms = 0;
    let e = c.validate().unwrap_err();
    assert!(
        matches!(e, dualstream::config::ConfigError::Impossible(_)),
        "{e:?}"
    );
    assert!(e.to_string().contains("chip.tms = 0"));
    let mut c = Config::default();
    c.chip.scene_buffer.slot_bytes = 32 << 10;
    let e = c.validate().unwrap_err().to_string();
    assert!(e.contains("smaller than one segment"), "{e}");
    let mut c = Config::default();
    c.chip.scene_buffer.bytes = 1024;
    assert!(c.validate().is_err());
    let e = Config::from_toml("[chip]\ntms = 0\n")
        .unwrap_err()
        .to_string();
    assert!(e.contains("chip.tms"), "{e}");
    let c = Config::from_toml("[chip.memory]\nmodel = \"gddr5\"\n").unwrap();
    assert_eq!(
        c.chip.memory.model,
        dualstream::units::memory::MemoryModel::Gddr5
    );
    let e = Config::from_toml("[chip.memory]\nmodel = \"ddr4\"\n")
        .unwrap_err()
        .to_string();
    assert!(e.contains("fixed") && e.contains("gddr5"), "{e}");
}

#[test]
fn a_full_destination_table_stops_with_a_named_error() {
    let s = scene("cornell", 8, 8, 1);
    let mut cfg = chip_cfg(1, 4);
    cfg.chip.scheduler.dest_entries = 1;
    let e = cycle_frame(&s, cfg).unwrap_err();
    assert!(
        matches!(e, RenderError::Chip(ChipError::Scheduler(_))),
        "{e:?}"
    );
    let e = e.to_string();
    assert!(e.contains("dest_entries"), "{e}");
    assert!(e.contains("chip.scheduler"), "{e}");
}

#[test]
fn the_destination_table_holds_only_the_working_sets_destinations() {
    // 8 KB segments: the cornell box's segment tree is several levels deep, so
    // with a table of exactly the most children of any segment a child can only
    // be admitted if its closed siblings' queues have left the table (as queue
    // records in DRAM), as the paper sizes it (§4.1).
    let s = scene("cornell", 16, 16, 2);
    let base = rcfg(8, None);
    let p = dualstream::render::prepare(&s, &base).unwrap();
    let max = p.info.children_max;
    assert!(
        max >= 2 && (p.info.segments as u64) > max + 1,
        "the scene needs grandchildren of the root: {} segments, at most {max} children",
        p.info.segments
    );
    let f = render(&s, Mode::Functional, &base, &mut |_| {}).unwrap();
    let mut cfg = chip_cfg(2, 4);
    cfg.chip.scheduler.dest_entries = max as u32;
    let c = cycle_frame(&s, cfg.clone()).unwrap();
    same_frame(&f, &c, "a table of the most children");
    // One entry fewer can never admit that segment: the scheduler names it.
    cfg.chip.scheduler.dest_entries = max as u32 - 1;
    let e = cycle_frame(&s, cfg).unwrap_err().to_string();
    assert!(
        e.contains(&format!("has {max} children")) && e.contains("at least"),
        "{e}"
    );
}

#[test]
fn the_watchdog_names_the_units_holding_work() {
    // A scene buffer that never answers: lines longer than the watchdog.
    let s = scene("cornell", 8, 8, 1);
    let mut cfg = chip_cfg(1, 2);
    cfg.chip.memory.latency = 5000;
    cfg.chip.watchdog_cycles = 1000;
    let e = render(
        &s,
        Mode::Cycle,
        &rcfg(8, Some((cfg, SimOptions::default()))),
        &mut |_| {},
    )
    .unwrap_err();
    assert!(
        matches!(e, RenderError::Chip(ChipError::Watchdog(_))),
        "{e:?}"
    );
    let e = e.to_string();
    assert!(e.contains("no progress for 1000 cycles"), "{e}");
    assert!(e.contains("chip.memory"), "{e}");
}

/// An impossible link in the chip's config fails the frame with the kernel's
/// error at the end of the chain: the frame's error has the chip's as its
/// source, that has the config's, and that the link's, with the same text.
#[test]
fn a_lower_layers_error_keeps_its_source_chain() {
    use dualstream::config::ConfigError;
    use dualstream::rtl::SimError;
    use std::error::Error;
    let s = scene("cornell", 8, 8, 1);
    let mut cfg = chip_cfg(1, 2);
    cfg.links.tm.delay = 0;
    let e = cycle_frame(&s, cfg).unwrap_err();
    let chip = e.source().and_then(|x| x.downcast_ref::<ChipError>());
    assert!(matches!(chip, Some(ChipError::Config(_))), "{e:?}");
    let config = chip.and_then(|x| x.source()?.downcast_ref::<ConfigError>());
    assert!(matches!(config, Some(ConfigError::Link(_))), "{e:?}");
    let link = config.and_then(|x| x.source()?.downcast_ref::<SimError>());
    match link {
        Some(SimError::LinkCfg { what, .. }) => assert_eq!(what, "links.tm"),
        l => panic!("expected the link's error at the end of the chain, got {l:?}"),
    }
    assert!(link.unwrap().source().is_none());
    // Each wrapper shows the text of the error it wraps.
    assert_eq!(e.to_string(), link.unwrap().to_string());
    assert!(e.to_string().contains("combinational"), "{e}");
}
