// Mounts Foxglove Studio 1.48 (its exports are globals of the UMD bundle) as its own web build
// does (packages/studio-web: Root.tsx, index.tsx), with three changes for a test: the layout comes
// from /layout.json into an in-memory layout storage (selected by the URL's layoutId), settings are
// in memory (telemetry and the launch preference screen off), and the only data source is the
// Foxglove WebSocket one (the URL's ds=foxglove-websocket&ds.url=ws://...).
/* global App, AppSetting, FoxgloveWebSocketDataSourceFactory, IdbExtensionLoader,
   overwriteFetch, waitForFonts, initI18n, React, ReactDOM */
"use strict";

class MemoryConfiguration {
  constructor(values) {
    this.values = new Map(Object.entries(values));
    this.listeners = new Map();
  }
  get(key) { return this.values.get(key); }
  async set(key, value) {
    this.values.set(key, value);
    for (const cb of this.listeners.get(key) ?? []) { cb(value); }
  }
  addChangeListener(key, cb) {
    if (!this.listeners.has(key)) { this.listeners.set(key, new Set()); }
    this.listeners.get(key).add(cb);
  }
  removeChangeListener(key, cb) { this.listeners.get(key)?.delete(cb); }
}

class MemoryLayoutStorage {
  constructor() { this.byNamespace = new Map(); }
  space(ns) {
    if (!this.byNamespace.has(ns)) { this.byNamespace.set(ns, new Map()); }
    return this.byNamespace.get(ns);
  }
  async list(ns) { return [...this.space(ns).values()]; }
  async get(ns, id) { return this.space(ns).get(id); }
  async put(ns, layout) { this.space(ns).set(layout.id, layout); return layout; }
  async delete(ns, id) { this.space(ns).delete(id); }
  async migrateUnnamespacedLayouts() {}
  async importLayouts() {}
}

async function boot() {
  window.onerror = (...args) => console.error("viewer error:", ...args);
  const layoutId = new URL(window.location.href).searchParams.get("layoutId") ?? "vizzy";
  const layoutData = await (await fetch("/layout.json")).json();
  const storage = new MemoryLayoutStorage();
  await storage.put("local", {
    id: layoutId, name: "vizzy", permission: "CREATOR_WRITE",
    baseline: { data: layoutData, savedAt: new Date().toISOString() },
    working: undefined, syncInfo: undefined,
  });
  const config = new MemoryConfiguration({
    [AppSetting.TELEMETRY_ENABLED]: false,
    [AppSetting.CRASH_REPORTING_ENABLED]: false,
    [AppSetting.UPDATES_ENABLED]: false,
    [AppSetting.HIDE_SIGN_IN_PROMPT]: true,
    [AppSetting.SHOW_OPEN_DIALOG_ON_STARTUP]: false,
    [AppSetting.LAUNCH_PREFERENCE]: "web",
  });
  overwriteFetch();
  await waitForFonts();
  await initI18n();
  ReactDOM.render(
    React.createElement(App, {
      deepLinks: [window.location.href],
      dataSources: [new FoxgloveWebSocketDataSourceFactory()],
      appConfiguration: config,
      layoutStorage: storage,
      extensionLoaders: [new IdbExtensionLoader("local")],
      enableGlobalCss: true,
    }),
    document.getElementById("root"),
  );
  console.debug("App rendered");
}

boot().catch((err) => console.error("viewer boot failed:", err));
