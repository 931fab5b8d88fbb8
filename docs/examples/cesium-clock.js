// The site at the date of a CesiumJS viewer's clock (docs/tiles.md, "Time
// in CesiumJS"). The clock spans the scene's period; as it moves, the
// viewer swaps to the slice of the current step, loaded hidden and shown
// once its tiles for the view are in. Every slice names a cluster's content
// by the same URL, so the browser's cache serves what earlier dates fetched.
import * as Cesium from "cesium";

export async function followClock(viewer, api, scene, { step = 86400, tileset = {} } = {}) {
  const about = await (await fetch(`${api}/scenes/${scene}`)).json();
  const start = Cesium.JulianDate.fromIso8601(about.time.start);
  const clock = viewer.clock;
  clock.startTime = start;
  clock.stopTime = Cesium.JulianDate.fromIso8601(about.time.end);
  clock.currentTime = start.clone();
  clock.clockRange = Cesium.ClockRange.CLAMPED;
  viewer.timeline?.zoomTo(clock.startTime, clock.stopTime);

  const slices = { shown: null, seconds: null, swapped: new Cesium.Event() };
  let wanted = null;
  clock.onTick.addEventListener(async () => {
    const elapsed = Cesium.JulianDate.secondsDifference(clock.currentTime, start);
    const seconds = Math.min(step * Math.floor(elapsed / step), about.time.seconds);
    if (seconds === wanted) return;
    wanted = seconds;
    if (seconds === slices.seconds) return; // back to the slice shown
    // The time in the path, not the query: CesiumJS carries a tileset
    // URL's query to every URL it names, which would make each date's
    // content URLs new ones.
    const next = await Cesium.Cesium3DTileset.fromUrl(
      `${api}/scenes/${scene}/tiles/${seconds}.json`,
      { ...tileset, show: false, preloadWhenHidden: true },
    );
    if (seconds !== wanted) return next.destroy(); // the clock moved on
    viewer.scene.primitives.add(next);
    const stop = viewer.scene.postRender.addEventListener(() => {
      if (seconds !== wanted) {
        stop();
        viewer.scene.primitives.remove(next);
      } else if (next.tilesLoaded) {
        stop();
        next.show = true;
        if (slices.shown) viewer.scene.primitives.remove(slices.shown);
        Object.assign(slices, { shown: next, seconds });
        slices.swapped.raiseEvent(next, seconds);
      }
    });
  });
  return slices;
}
