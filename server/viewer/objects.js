// The scene's objects in the page: the property panel of the selected one
// (GET .../objects/{index}?by=index&time=T, asked again as the time moves,
// one request in flight and only the newest time waiting) and the search
// (GET .../objects?q=, every page).

const SEARCH_PAGE = 1000;

function text(value) {
  return value === null || value === undefined || value === "" ? "-" : String(value);
}

function escape(value) {
  return text(value).replace(/[&<>"]/g, (c) => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;" })[c]);
}

export class ObjectPanel {
  // element: the panel; base: the scene's API path; getJson(url) -> Promise;
  // loaded(answer): each object answer shown
  constructor(element, base, getJson, formatDate, loaded) {
    this.element = element;
    this.loaded = loaded;
    this.base = base;
    this.getJson = getJson;
    this.formatDate = formatDate;
    this.index = null; // the selected object's index
    this.shown = null; // the answer on screen
    this.shownTime = null; // the time it was asked for
    this.wanted = null; // the time the panel should show
    this.inFlight = false;
    this.error = null;
  }

  // index: the selected object, or null to close the panel.
  show(index, t) {
    this.index = index;
    this.shown = null;
    this.error = null;
    if (index === null) {
      this.element.hidden = true;
      this.element.innerHTML = "";
      return;
    }
    this.setTime(t);
  }

  setTime(t) {
    if (this.index === null) return;
    this.wanted = t;
    this.fetch();
  }

  async fetch() {
    if (this.inFlight || this.index === null) return;
    const index = this.index;
    const t = this.wanted;
    if (this.shown && this.shown.index === index && this.shownTime === t) return;
    this.inFlight = true;
    try {
      const answer = await this.getJson(`${this.base}/objects/${index}?by=index&time=${t}`);
      if (this.index === index) {
        this.shown = answer;
        this.shownTime = t;
        this.error = null;
        this.render();
        this.loaded(answer);
      }
    } catch (e) {
      if (this.index === index) {
        this.error = e.message;
        this.element.hidden = false;
        this.element.innerHTML = `<p class="error">${escape(e.message)}</p>`;
      }
    } finally {
      this.inFlight = false;
    }
    if (this.index !== null && !this.error && (this.index !== index || this.wanted !== t)) this.fetch();
  }

  // True when the panel shows the selection at the time it was last given.
  settled() {
    if (this.index === null) return true;
    if (this.error) return true;
    return !this.inFlight && !!this.shown && this.shown.index === this.index && this.shownTime === this.wanted;
  }

  render() {
    const o = this.shown;
    const rows = [
      ["id", o.id],
      ["name", o.name],
      ["class", o.class],
      ["storey", o.properties.storey],
      ["index", o.index],
    ];
    const others = Object.entries(o.properties).filter(([k]) => !["name", "ifc_class", "class", "storey"].includes(k));
    const tasks = o.tasks.map((k) => `<tr data-task="${escape(k.id)}"><td>${escape(k.name || k.id)}<br><small>${escape(k.type)}</small></td>`
      + `<td>${escape(k.start_date.slice(0, 16).replace("T", " "))}<br>${escape(k.finish_date.slice(0, 16).replace("T", " "))}</td>`
      + `<td class="state-${escape(k.state)}">${escape(k.state.replace("_", " "))}</td></tr>`).join("");
    this.element.innerHTML = `<button class="close" title="Clear the selection">&times;</button>`
      + `<table class="fields">${rows.map(([k, v]) => `<tr><th>${k}</th><td data-field="${k}">${escape(v)}</td></tr>`).join("")}`
      + others.map(([k, v]) => `<tr><th>${escape(k)}</th><td>${escape(v)}</td></tr>`).join("")
      + `</table><p>At ${escape(this.formatDate(o.at.time))}: <b data-field="present">${o.present ? "present" : "absent"}</b></p>`
      + (tasks ? `<table class="tasks"><tr><th>task</th><th>start / finish</th><th>state</th></tr>${tasks}</table>` : "<p>No task acts on it.</p>");
    this.element.hidden = false;
  }
}

// Every object matching q, in scene order: their indices.
export async function searchObjects(base, q, getJson) {
  const indices = [];
  let cursor = null;
  do {
    const page = await getJson(`${base}/objects?q=${encodeURIComponent(q)}&limit=${SEARCH_PAGE}${cursor ? `&cursor=${encodeURIComponent(cursor)}` : ""}`);
    for (const item of page.items) indices.push(item.index);
    cursor = page.next;
  } while (cursor);
  return indices;
}

// Every object's class or storey (`field` of the list items), by index,
// null for none: the whole object list, a page at a time.
export async function objectField(base, count, field, getJson) {
  const values = new Array(count).fill(null);
  let cursor = null;
  do {
    const page = await getJson(`${base}/objects?limit=${SEARCH_PAGE}${cursor ? `&cursor=${encodeURIComponent(cursor)}` : ""}`);
    for (const item of page.items) {
      const v = item[field];
      if (item.index < count) values[item.index] = v === undefined || v === null || v === "" ? null : String(v);
    }
    cursor = page.next;
  } while (cursor);
  return values;
}
