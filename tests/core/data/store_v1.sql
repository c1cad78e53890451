-- A results store at schema version 1, made by coadapt at commit 9a767d7 (the last with
-- SCHEMA_VERSION = 1) through ResultsStore's own methods (create_run, record_evaluations,
-- record_training, record_checkpoint, finish_run, save_grid, set_cell), dumped with
-- sqlite3's iterdump: the tables exactly as SQLite recorded their CREATE statements.
BEGIN TRANSACTION;
CREATE TABLE checkpoints (
	id INTEGER NOT NULL, 
	run_id VARCHAR(80) NOT NULL, 
	"outer" INTEGER NOT NULL, 
	path TEXT NOT NULL, 
	created_at FLOAT NOT NULL, 
	PRIMARY KEY (id), 
	CONSTRAINT uq_checkpoint UNIQUE (run_id, "outer", path), 
	FOREIGN KEY(run_id) REFERENCES runs (id) ON DELETE CASCADE
);
INSERT INTO "checkpoints" VALUES(1,'20261201-000000-ours-torque-s0-abc120',0,'checkpoints/outer_0.pt',1.79628953851532745366e+09);
INSERT INTO "checkpoints" VALUES(2,'20261201-000000-ours-torque-s0-abc120',1,'checkpoints/outer_1.pt',1.79628953853056979174e+09);
INSERT INTO "checkpoints" VALUES(3,'20261201-010000-ours-power+torque-s1-abc121',0,'checkpoints/outer_0.pt',1.79628953855767774586e+09);
INSERT INTO "checkpoints" VALUES(4,'20261201-010000-ours-power+torque-s1-abc121',1,'checkpoints/outer_1.pt',1.79628953856844902035e+09);
INSERT INTO "checkpoints" VALUES(5,'20261201-020000-bo-specialized-tracking-s2-abc122',0,'checkpoints/outer_0.pt',1.79628953858095836634e+09);
INSERT INTO "checkpoints" VALUES(6,'20261201-020000-bo-specialized-tracking-s2-abc122',1,'checkpoints/outer_1.pt',1.79628953860378670691e+09);
CREATE TABLE evaluations (
	id INTEGER NOT NULL, 
	run_id VARCHAR(80) NOT NULL, 
	"outer" INTEGER NOT NULL, 
	"inner" INTEGER NOT NULL, 
	idx INTEGER NOT NULL, 
	kind VARCHAR(20) NOT NULL, 
	design TEXT NOT NULL, 
	costs TEXT NOT NULL, 
	surrogate_error TEXT, 
	interactions BIGINT NOT NULL, 
	seconds FLOAT NOT NULL, 
	simulator VARCHAR(40), 
	created_at FLOAT NOT NULL, 
	PRIMARY KEY (id), 
	CONSTRAINT uq_evaluation UNIQUE (run_id, "outer", "inner", kind, idx), 
	FOREIGN KEY(run_id) REFERENCES runs (id) ON DELETE CASCADE
);
INSERT INTO "evaluations" VALUES(1,'20261201-000000-ours-torque-s0-abc120',0,0,0,'real','[0.5, 1.5]','{"torque": 0.25}',NULL,8000,1.5,NULL,1.79628953850182652473e+09);
INSERT INTO "evaluations" VALUES(2,'20261201-000000-ours-torque-s0-abc120',0,0,1,'real','[0.625, 1.4375]','{"torque": 0.5}',NULL,8000,1.75,NULL,1.79628953850182652473e+09);
INSERT INTO "evaluations" VALUES(3,'20261201-000000-ours-torque-s0-abc120',0,0,2,'real','[0.75, 1.375]','{"torque": 0.75}',NULL,8000,2.0,NULL,1.79628953850182652473e+09);
INSERT INTO "evaluations" VALUES(4,'20261201-000000-ours-torque-s0-abc120',0,1,0,'real','[0.5, 1.4375]','{"torque": 0.25}',NULL,8000,1.5,NULL,1796289538.50466);
INSERT INTO "evaluations" VALUES(5,'20261201-000000-ours-torque-s0-abc120',0,1,1,'real','[0.625, 1.375]','{"torque": 0.5}',NULL,8000,1.75,NULL,1796289538.50466);
INSERT INTO "evaluations" VALUES(6,'20261201-000000-ours-torque-s0-abc120',0,1,2,'real','[0.75, 1.3125]','{"torque": 0.75}',NULL,8000,2.0,NULL,1796289538.50466);
INSERT INTO "evaluations" VALUES(7,'20261201-000000-ours-torque-s0-abc120',0,2,0,'surrogate','[0.75, 0.875]','{"torque": 1.125}','{"torque": -0.0625}',0,0.01,NULL,1.79628953850570774073e+09);
INSERT INTO "evaluations" VALUES(8,'20261201-000000-ours-torque-s0-abc120',0,2,1,'surrogate','[0.75, 1.0]','{"torque": 2.125}','{"torque": -0.125}',0,0.01,NULL,1.79628953850570774073e+09);
INSERT INTO "evaluations" VALUES(9,'20261201-000000-ours-torque-s0-abc120',1,0,0,'real','[0.5, 1.4375]','{"torque": 0.375}',NULL,8000,1.5,NULL,1.79628953852005410199e+09);
INSERT INTO "evaluations" VALUES(10,'20261201-000000-ours-torque-s0-abc120',1,0,1,'real','[0.625, 1.375]','{"torque": 0.625}',NULL,8000,1.75,NULL,1.79628953852005410199e+09);
INSERT INTO "evaluations" VALUES(11,'20261201-000000-ours-torque-s0-abc120',1,0,2,'real','[0.75, 1.3125]','{"torque": 0.875}',NULL,8000,2.0,NULL,1.79628953852005410199e+09);
INSERT INTO "evaluations" VALUES(12,'20261201-000000-ours-torque-s0-abc120',1,1,0,'real','[0.5, 1.375]','{"torque": 0.375}',NULL,8000,1.5,NULL,1.79628953852602601046e+09);
INSERT INTO "evaluations" VALUES(13,'20261201-000000-ours-torque-s0-abc120',1,1,1,'real','[0.625, 1.3125]','{"torque": 0.625}',NULL,8000,1.75,NULL,1.79628953852602601046e+09);
INSERT INTO "evaluations" VALUES(14,'20261201-000000-ours-torque-s0-abc120',1,1,2,'real','[0.75, 1.25]','{"torque": 0.875}',NULL,8000,2.0,NULL,1.79628953852602601046e+09);
INSERT INTO "evaluations" VALUES(15,'20261201-000000-ours-torque-s0-abc120',1,2,0,'surrogate','[0.75, 0.875]','{"torque": 1.125}','{"torque": -0.0625}',0,0.01,NULL,1.79628953852951645854e+09);
INSERT INTO "evaluations" VALUES(16,'20261201-000000-ours-torque-s0-abc120',1,2,1,'surrogate','[0.75, 1.0]','{"torque": 2.125}','{"torque": -0.125}',0,0.01,NULL,1.79628953852951645854e+09);
INSERT INTO "evaluations" VALUES(17,'20261201-000000-ours-torque-s0-abc120',-1,0,0,'sim2sim','[0.75, 0.875]','{"torque": 2.5}',NULL,4000,3.0,'pybullet',1.7962895385308365821e+09);
INSERT INTO "evaluations" VALUES(18,'20261201-000000-ours-torque-s0-abc120',-1,0,1,'sim2sim','[0.75, 0.875]','{"torque": 3.5}',NULL,4000,3.0,'pybullet',1.7962895385308365821e+09);
INSERT INTO "evaluations" VALUES(19,'20261201-000000-ours-torque-s0-abc120',-2,0,0,'common','[0.75, 0.875]','{"torque": 2.0}',NULL,4000,2.0,NULL,1.79628953854234433172e+09);
INSERT INTO "evaluations" VALUES(20,'20261201-000000-ours-torque-s0-abc120',-2,0,1,'common','[0.75, 0.875]','{"torque": 2.5}',NULL,4000,2.0,NULL,1.79628953854234433172e+09);
INSERT INTO "evaluations" VALUES(21,'20261201-010000-ours-power+torque-s1-abc121',0,0,0,'real','[0.625, 1.5]','{"power": 1.25, "torque": 1.75}',NULL,8000,1.5,NULL,1.79628953854884815212e+09);
INSERT INTO "evaluations" VALUES(22,'20261201-010000-ours-power+torque-s1-abc121',0,0,1,'real','[0.75, 1.4375]','{"power": 1.5, "torque": 2.0}',NULL,8000,1.75,NULL,1.79628953854884815212e+09);
INSERT INTO "evaluations" VALUES(23,'20261201-010000-ours-power+torque-s1-abc121',0,0,2,'real','[0.875, 1.375]','{"power": 1.75, "torque": 2.25}',NULL,8000,2.0,NULL,1.79628953854884815212e+09);
INSERT INTO "evaluations" VALUES(24,'20261201-010000-ours-power+torque-s1-abc121',0,1,0,'real','[0.625, 1.4375]','{"power": 1.25, "torque": 1.75}',NULL,8000,1.5,NULL,1.79628953854964041715e+09);
INSERT INTO "evaluations" VALUES(25,'20261201-010000-ours-power+torque-s1-abc121',0,1,1,'real','[0.75, 1.375]','{"power": 1.5, "torque": 2.0}',NULL,8000,1.75,NULL,1.79628953854964041715e+09);
INSERT INTO "evaluations" VALUES(26,'20261201-010000-ours-power+torque-s1-abc121',0,1,2,'real','[0.875, 1.3125]','{"power": 1.75, "torque": 2.25}',NULL,8000,2.0,NULL,1.79628953854964041715e+09);
INSERT INTO "evaluations" VALUES(27,'20261201-010000-ours-power+torque-s1-abc121',0,2,0,'surrogate','[0.75, 0.875]','{"power": 1.125, "torque": 1.125}','{"power": -0.0625, "torque": -0.0625}',0,0.01,NULL,1.79628953855037093163e+09);
INSERT INTO "evaluations" VALUES(28,'20261201-010000-ours-power+torque-s1-abc121',0,2,1,'surrogate','[0.75, 1.0]','{"power": 2.125, "torque": 2.125}','{"power": -0.125, "torque": -0.125}',0,0.01,NULL,1.79628953855037093163e+09);
INSERT INTO "evaluations" VALUES(29,'20261201-010000-ours-power+torque-s1-abc121',1,0,0,'real','[0.625, 1.4375]','{"power": 1.375, "torque": 1.875}',NULL,8000,1.5,NULL,1.7962895385596487522e+09);
INSERT INTO "evaluations" VALUES(30,'20261201-010000-ours-power+torque-s1-abc121',1,0,1,'real','[0.75, 1.375]','{"power": 1.625, "torque": 2.125}',NULL,8000,1.75,NULL,1.7962895385596487522e+09);
INSERT INTO "evaluations" VALUES(31,'20261201-010000-ours-power+torque-s1-abc121',1,0,2,'real','[0.875, 1.3125]','{"power": 1.875, "torque": 2.375}',NULL,8000,2.0,NULL,1.7962895385596487522e+09);
INSERT INTO "evaluations" VALUES(32,'20261201-010000-ours-power+torque-s1-abc121',1,1,0,'real','[0.625, 1.375]','{"power": 1.375, "torque": 1.875}',NULL,8000,1.5,NULL,1.79628953856412577633e+09);
INSERT INTO "evaluations" VALUES(33,'20261201-010000-ours-power+torque-s1-abc121',1,1,1,'real','[0.75, 1.3125]','{"power": 1.625, "torque": 2.125}',NULL,8000,1.75,NULL,1.79628953856412577633e+09);
INSERT INTO "evaluations" VALUES(34,'20261201-010000-ours-power+torque-s1-abc121',1,1,2,'real','[0.875, 1.25]','{"power": 1.875, "torque": 2.375}',NULL,8000,2.0,NULL,1.79628953856412577633e+09);
INSERT INTO "evaluations" VALUES(35,'20261201-010000-ours-power+torque-s1-abc121',1,2,0,'surrogate','[0.75, 0.875]','{"power": 1.125, "torque": 1.125}','{"power": -0.0625, "torque": -0.0625}',0,0.01,NULL,1.79628953856731104848e+09);
INSERT INTO "evaluations" VALUES(36,'20261201-010000-ours-power+torque-s1-abc121',1,2,1,'surrogate','[0.75, 1.0]','{"power": 2.125, "torque": 2.125}','{"power": -0.125, "torque": -0.125}',0,0.01,NULL,1.79628953856731104848e+09);
INSERT INTO "evaluations" VALUES(37,'20261201-020000-bo-specialized-tracking-s2-abc122',0,0,0,'real','[0.75, 1.5]','{"tracking": 2.25}',NULL,8000,1.5,NULL,1.7962895385689322948e+09);
INSERT INTO "evaluations" VALUES(38,'20261201-020000-bo-specialized-tracking-s2-abc122',0,0,1,'real','[0.875, 1.4375]','{"tracking": 2.5}',NULL,8000,1.75,NULL,1.7962895385689322948e+09);
INSERT INTO "evaluations" VALUES(39,'20261201-020000-bo-specialized-tracking-s2-abc122',0,0,2,'real','[1.0, 1.375]','{"tracking": 2.75}',NULL,8000,2.0,NULL,1.7962895385689322948e+09);
INSERT INTO "evaluations" VALUES(40,'20261201-020000-bo-specialized-tracking-s2-abc122',0,1,0,'real','[0.75, 1.4375]','{"tracking": 2.25}',NULL,8000,1.5,NULL,1.79628953856969451907e+09);
INSERT INTO "evaluations" VALUES(41,'20261201-020000-bo-specialized-tracking-s2-abc122',0,1,1,'real','[0.875, 1.375]','{"tracking": 2.5}',NULL,8000,1.75,NULL,1.79628953856969451907e+09);
INSERT INTO "evaluations" VALUES(42,'20261201-020000-bo-specialized-tracking-s2-abc122',0,1,2,'real','[1.0, 1.3125]','{"tracking": 2.75}',NULL,8000,2.0,NULL,1.79628953856969451907e+09);
INSERT INTO "evaluations" VALUES(43,'20261201-020000-bo-specialized-tracking-s2-abc122',0,2,0,'surrogate','[0.75, 0.875]','{"tracking": 1.125}','{"tracking": -0.0625}',0,0.01,NULL,1.79628953857044601442e+09);
INSERT INTO "evaluations" VALUES(44,'20261201-020000-bo-specialized-tracking-s2-abc122',0,2,1,'surrogate','[0.75, 1.0]','{"tracking": 2.125}','{"tracking": -0.125}',0,0.01,NULL,1.79628953857044601442e+09);
INSERT INTO "evaluations" VALUES(45,'20261201-020000-bo-specialized-tracking-s2-abc122',1,0,0,'real','[0.75, 1.4375]','{"tracking": 2.375}',NULL,8000,1.5,NULL,1.79628953858242177959e+09);
INSERT INTO "evaluations" VALUES(46,'20261201-020000-bo-specialized-tracking-s2-abc122',1,0,1,'real','[0.875, 1.375]','{"tracking": 2.625}',NULL,8000,1.75,NULL,1.79628953858242177959e+09);
INSERT INTO "evaluations" VALUES(47,'20261201-020000-bo-specialized-tracking-s2-abc122',1,0,2,'real','[1.0, 1.3125]','{"tracking": 2.875}',NULL,8000,2.0,NULL,1.79628953858242177959e+09);
INSERT INTO "evaluations" VALUES(48,'20261201-020000-bo-specialized-tracking-s2-abc122',1,1,0,'real','[0.75, 1.375]','{"tracking": 2.375}',NULL,8000,1.5,NULL,1.79628953858832812306e+09);
INSERT INTO "evaluations" VALUES(49,'20261201-020000-bo-specialized-tracking-s2-abc122',1,1,1,'real','[0.875, 1.3125]','{"tracking": 2.625}',NULL,8000,1.75,NULL,1.79628953858832812306e+09);
INSERT INTO "evaluations" VALUES(50,'20261201-020000-bo-specialized-tracking-s2-abc122',1,1,2,'real','[1.0, 1.25]','{"tracking": 2.875}',NULL,8000,2.0,NULL,1.79628953858832812306e+09);
INSERT INTO "evaluations" VALUES(51,'20261201-020000-bo-specialized-tracking-s2-abc122',1,2,0,'surrogate','[0.75, 0.875]','{"tracking": 1.125}','{"tracking": -0.0625}',0,0.01,NULL,1.79628953859451651574e+09);
INSERT INTO "evaluations" VALUES(52,'20261201-020000-bo-specialized-tracking-s2-abc122',1,2,1,'surrogate','[0.75, 1.0]','{"tracking": 2.125}','{"tracking": -0.125}',0,0.01,NULL,1.79628953859451651574e+09);
CREATE TABLE grid_cells (
	grid_id VARCHAR(80) NOT NULL, 
	cell VARCHAR(200) NOT NULL, 
	run_id VARCHAR(80), 
	status VARCHAR(20) NOT NULL, 
	attempts INTEGER NOT NULL, 
	last_error TEXT, 
	updated_at FLOAT NOT NULL, 
	PRIMARY KEY (grid_id, cell), 
	FOREIGN KEY(grid_id) REFERENCES grids (id) ON DELETE CASCADE
);
INSERT INTO "grid_cells" VALUES('g-1','method=ours|objective=torque|seed=0','20261201-000000-ours-torque-s0-abc120','finished',1,NULL,1.79628953860692787175e+09);
INSERT INTO "grid_cells" VALUES('g-1','method=ours|objective=power,torque|seed=1','20261201-010000-ours-power+torque-s1-abc121','failed',2,'exit 1: killed',1.79628953863698601718e+09);
CREATE TABLE grids (
	id VARCHAR(80) NOT NULL, 
	spec TEXT NOT NULL, 
	created_at FLOAT NOT NULL, 
	updated_at FLOAT NOT NULL, 
	PRIMARY KEY (id)
);
INSERT INTO "grids" VALUES('g-1','{"methods": ["ours"], "objectives": ["torque", "power,torque"], "seeds": [0, 1]}',1.79628953860469222063e+09,1.79628953860469222063e+09);
CREATE TABLE runs (
	id VARCHAR(80) NOT NULL, 
	grid_id VARCHAR(80), 
	cell VARCHAR(200), 
	method VARCHAR(40), 
	objectives VARCHAR(200), 
	terrain VARCHAR(40), 
	optimizer VARCHAR(40), 
	simulator VARCHAR(40), 
	robot VARCHAR(40), 
	preset VARCHAR(40), 
	seed INTEGER, 
	config TEXT, 
	code_version VARCHAR(40), 
	git_commit VARCHAR(60), 
	status VARCHAR(20) NOT NULL, 
	run_dir TEXT, 
	created_at FLOAT NOT NULL, 
	updated_at FLOAT NOT NULL, 
	finished_at FLOAT, 
	summary TEXT, 
	PRIMARY KEY (id)
);
INSERT INTO "runs" VALUES('20261201-000000-ours-torque-s0-abc120','g-1','method=ours|objective=torque|seed=0','ours','torque','flat','pso','mujoco','kuafu','smoke',0,'{"design_space": {"variables": [{"high": 1.5, "low": 0.5, "name": "thigh_scale", "type": "continuous"}, {"high": 1.5, "low": 0.5, "name": "shank_scale", "type": "continuous"}]}, "grid_cell": "method=ours|objective=torque|seed=0", "grid_id": "g-1", "method": "ours", "objective": "torque", "optimizer": "pso", "preset": "smoke", "robot": "kuafu", "seed": 0, "sim": "mujoco", "terrain": "flat"}','0.1.0','9a767d779dbc9d7108038274f5170ae04c1e0fae+dirty','finished','/data/runs/r0',1.79628953835512638094e+09,1.79628953854815363888e+09,1.79628953854815363888e+09,'{"best_cost": 1.5, "best_design": [0.75, 0.875], "improvement": 0.125, "improvement_se": 0.03125}');
INSERT INTO "runs" VALUES('20261201-010000-ours-power+torque-s1-abc121','g-1','method=ours|objective=power,torque|seed=1','ours','power,torque','flat','nsga2','mujoco','kuafu','smoke',1,'{"design_space": {"variables": [{"high": 1.5, "low": 0.5, "name": "thigh_scale", "type": "continuous"}, {"high": 1.5, "low": 0.5, "name": "shank_scale", "type": "continuous"}]}, "grid_cell": "method=ours|objective=power,torque|seed=1", "grid_id": "g-1", "method": "ours", "objective": "power,torque", "optimizer": "nsga2", "preset": "smoke", "robot": "kuafu", "seed": 1, "sim": "mujoco", "terrain": "flat"}','0.1.0','9a767d779dbc9d7108038274f5170ae04c1e0fae+dirty','finished','/data/runs/r1',1.79628953845720386499e+09,1.79628953856872177127e+09,1.79628953856872177127e+09,'{"best_cost": 2.5, "best_design": [0.75, 0.875], "improvement": 0.125, "improvement_se": 0.03125}');
INSERT INTO "runs" VALUES('20261201-020000-bo-specialized-tracking-s2-abc122',NULL,NULL,'bo-specialized','tracking','flat','pso','mujoco','kuafu','smoke',2,'{"design_space": {"variables": [{"high": 1.5, "low": 0.5, "name": "thigh_scale", "type": "continuous"}, {"high": 1.5, "low": 0.5, "name": "shank_scale", "type": "continuous"}]}, "grid_cell": null, "grid_id": null, "method": "bo-specialized", "objective": "tracking", "optimizer": "pso", "preset": "smoke", "robot": "kuafu", "seed": 2, "sim": "mujoco", "terrain": "flat"}','0.1.0','9a767d779dbc9d7108038274f5170ae04c1e0fae+dirty','interrupted','/data/runs/r2',1.79628953848614287373e+09,1.79628953860414791103e+09,NULL,NULL);
CREATE TABLE store_info (
	"key" VARCHAR(40) NOT NULL, 
	value VARCHAR(200) NOT NULL, 
	PRIMARY KEY ("key")
);
INSERT INTO "store_info" VALUES('schema_version','1');
CREATE TABLE training_phases (
	id INTEGER NOT NULL, 
	run_id VARCHAR(80) NOT NULL, 
	"outer" INTEGER NOT NULL, 
	idx INTEGER NOT NULL, 
	steps BIGINT NOT NULL, 
	seconds FLOAT NOT NULL, 
	final_reward FLOAT, 
	extra TEXT, 
	created_at FLOAT NOT NULL, 
	PRIMARY KEY (id), 
	CONSTRAINT uq_training_phase UNIQUE (run_id, "outer", idx), 
	FOREIGN KEY(run_id) REFERENCES runs (id) ON DELETE CASCADE
);
INSERT INTO "training_phases" VALUES(1,'20261201-000000-ours-torque-s0-abc120',0,0,120000,42.5,3.25,'{"kl": 0.0125}',1.79628953850648570055e+09);
INSERT INTO "training_phases" VALUES(2,'20261201-000000-ours-torque-s0-abc120',1,0,120000,43.5,4.25,'{"kl": 0.0125}',1.79628953853015089041e+09);
INSERT INTO "training_phases" VALUES(3,'20261201-010000-ours-power+torque-s1-abc121',0,0,120000,42.5,3.25,'{"kl": 0.0125}',1.7962895385510349274e+09);
INSERT INTO "training_phases" VALUES(4,'20261201-010000-ours-power+torque-s1-abc121',1,0,120000,43.5,4.25,'{"kl": 0.0125}',1.79628953856801056856e+09);
INSERT INTO "training_phases" VALUES(5,'20261201-020000-bo-specialized-tracking-s2-abc122',0,0,120000,42.5,3.25,'{"kl": 0.0125}',1.79628953857100939752e+09);
INSERT INTO "training_phases" VALUES(6,'20261201-020000-bo-specialized-tracking-s2-abc122',1,0,120000,43.5,4.25,'{"kl": 0.0125}',1.79628953859931206706e+09);
CREATE INDEX ix_runs_grid_id ON runs (grid_id);
CREATE INDEX ix_runs_method ON runs (method);
CREATE INDEX ix_runs_cell ON runs (cell);
CREATE INDEX ix_evaluations_run ON evaluations (run_id, kind);
COMMIT;
