// The share's scans per patient, newest first, each linking to the viewer.
const root = document.getElementById('scans');
const text = (tag, s) => { const e = document.createElement(tag); e.textContent = s; return e; };
fetch('/api/scans').then((r) => r.json()).then((data) => {
	root.textContent = '';
	const patients = Object.keys(data.patients).sort();
	if (!patients.length) root.textContent = 'no scans on the share';
	for (const p of patients) {
		const div = document.createElement('div');
		div.className = 'patient';
		div.appendChild(text('h2', p || 'scan'));
		for (const s of data.patients[p].slice().reverse()) {
			const a = document.createElement('a');
			a.className = 'scan';
			a.href = '/view.html?mesh=' + encodeURIComponent(s.glb);
			if (s.thumbnail) { const img = document.createElement('img'); img.src = s.thumbnail; img.alt = ''; a.appendChild(img); }
			a.appendChild(text('span', s.base));
			div.appendChild(a);
		}
		root.appendChild(div);
	}
}, (e) => { root.textContent = 'cannot list the scans: ' + e; });
