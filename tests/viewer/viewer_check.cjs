// Drives the viewer in headless Chromium (puppeteer-core, Debian's chromium): opens the page,
// waits until the model is drawn, screenshots it without the toolbar (for the silhouette) and with
// it (for docs), then measures between two given mesh points (mm) by clicking where the viewer's
// camera puts them, and prints one JSON line with what the page reported.
// usage: node viewer_check.cjs PUPPETEER_DIR URL W H SHOT.png UI_SHOT.png AX AY AZ BX BY BZ
const [pdir, url, w, h, shot, uiShot, ...pts] = process.argv.slice(2);
const puppeteer = require(pdir);
const [a, b] = [pts.slice(0, 3).map(Number), pts.slice(3, 6).map(Number)];
(async () => {
	const browser = await puppeteer.launch({
		executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
		headless: true,
		args: ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist',
			'--disable-dev-shm-usage', '--no-first-run', '--disable-extensions'],
	});
	const out = { console: [] };
	try {
		const page = await browser.newPage();
		page.on('console', (m) => out.console.push(m.type() + ': ' + m.text()));
		page.on('pageerror', (e) => out.console.push('pageerror: ' + e.message));
		await page.setViewport({ width: Number(w), height: Number(h), deviceScaleFactor: 1 });
		const t0 = Date.now();
		await page.goto(url, { waitUntil: 'load', timeout: 60000 });
		await page.waitForFunction('window.facescanView && (window.facescanView.ready || window.facescanView.error)',
			{ timeout: 90000, polling: 100 });
		out.error = await page.evaluate('window.facescanView.error');
		out.load_ms = Date.now() - t0;
		if (!out.error) {
			await page.evaluate('window.facescanView.setUi(false)');
			await page.screenshot({ path: shot });
			await page.evaluate('window.facescanView.setUi(true)');
			await page.click('#measure');
			for (const p of [a, b]) {
				const [x, y] = await page.evaluate((p) => window.facescanView.project(p[0], p[1], p[2]), p);
				out.clicks = (out.clicks || []).concat([[x, y]]);
				await page.mouse.click(x, y);
			}
			await page.waitForFunction('window.facescanView.measurement_mm !== null', { timeout: 10000 });
			out.measurement_mm = await page.evaluate('window.facescanView.measurement_mm');
			out.readout = await page.$eval('#distance', (e) => e.textContent);
			await page.screenshot({ path: uiShot });
		}
	} catch (e) {
		out.error = String(e);
	}
	await browser.close();
	console.log(JSON.stringify(out));
})();
