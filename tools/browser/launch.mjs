// Starts Debian's chromium headless for the browser tests, with the flags
// that keep it off the network (this machine has none but loopback).
import { chromium } from "playwright-core";

export const CHROMIUM = process.env.HDLOD_CHROMIUM || "/usr/bin/chromium";

export async function launch() {
  return chromium.launch({
    executablePath: CHROMIUM,
    headless: true,
    args: [
      "--no-sandbox",
      "--disable-gpu",
      "--use-angle=swiftshader",
      "--enable-unsafe-swiftshader",
      "--disable-quic",
      "--no-first-run",
      "--disable-background-networking",
      "--disable-component-update",
      "--disable-sync",
    ],
  });
}
