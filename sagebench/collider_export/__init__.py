"""Physics for exported scenes: convex collider parts (exact pieces or CoACD), USD stage and MuJoCo MJCF writers,
and one scene's whole export (scene_export)."""
